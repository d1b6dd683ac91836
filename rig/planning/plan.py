"""Campaign → plan: the points in order, the moves checked, and the rig-time estimates.

A plan is data. Its points come from the campaign's tables (rig.planning.table: stable ids, motors, skip
reasons) or, for `sampling: {mode: adaptive}`, are the first pass over the candidate domain
(rig.planning.candidates; the batches after it are chosen while the run goes, rig.analysis.adaptive). The
order is the campaign's (`table`) or a travel-time optimised one (`optimised`, rig.planning.ordering); both are
deterministic, so a resume that rebuilds the plan gets the same order. Moves through the rig's forbidden zones
(rig.planning.collisions) are checked in the final order; the ordering goes block by block, so the work grows
linearly with the points.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Literal

import numpy as np

from rig.config.campaign import Campaign
from rig.config.rigfile import AxesConfig, RigConfig
from rig.config.zones import ForbiddenZone
from rig.physics import geometry as geo
from rig.planning.candidates import candidate_plan, first_pass
from rig.planning.collisions import path_crosses, zones_of
from rig.planning.ordering import START_DEG, arm_branches, order_plan, path_time_s
from rig.planning.points import Motors, Plan, PlannedPoint, SkippedPoint, as_motors
from rig.planning.table import table_plan

Ordering = Literal["optimised", "table"]


def build_plan(campaign: Campaign, rig: RigConfig, ordering: Ordering | None = None) -> Plan:
    """Plan every (incidence, view) pair; leave out, with a reason, what cannot be measured. An adaptive
    campaign's plan is its first pass: every candidate incidence is a series, the first pass its points.

    `ordering`: `table` (campaign order) or `optimised` (least rig time);
    default the campaign's `ordering`, else optimised.
    """
    ordering = ordering or getattr(campaign, "ordering", "optimised")
    if ordering not in ("optimised", "table"):
        raise ValueError(f"ordering must be 'optimised' or 'table', got {ordering!r}")
    if campaign.sampling.mode == "adaptive":
        candidates = candidate_plan(campaign, rig)
        plan = Plan(candidates.series, tuple(first_pass(campaign, candidates)), ())
    else:
        plan = table_plan(campaign, rig)
    return _in_order(plan, rig.axes, zones_of(rig), ordering)


def _in_order(plan: Plan, axes: AxesConfig, zones: Sequence[ForbiddenZone], ordering: Ordering) -> Plan:
    """The table plan in `ordering`, with the moves that would cross a forbidden zone checked."""
    if ordering == "optimised":
        plan = order_plan(plan, axes, zones, START_DEG)
    return drop_colliding_moves(plan, axes, zones, START_DEG)


def _other_branches(motors: Motors, limits: geo.AxisLimits, zones: Sequence[ForbiddenZone]) -> list[Motors]:
    """The position's twins on the other arm branch that are inside the limits and outside every zone."""
    twins = arm_branches(np.array([motors]), limits, zones)[0, 1:]
    return [as_motors(m) for m in twins if np.all(np.isfinite(m))]


def drop_colliding_moves(plan: Plan, axes: AxesConfig, zones: Sequence[ForbiddenZone],
                         start: Sequence[float] = START_DEG) -> Plan:
    """Check every move in plan order; a move across a forbidden zone goes to the point's other arm
    branch if that one's move is clear, else the point is left out (reason `collision:<zone>`).

    The next move then starts from the last point kept.
    """
    if not zones:
        return plan
    limits = axes.limits()
    here: Sequence[float] = tuple(start)
    kept: list[PlannedPoint] = []
    dropped: list[SkippedPoint] = []
    for p in plan.points:
        zone = path_crosses(here, p.motors_deg, zones, axes)
        clear = p.motors_deg if zone is None else next(
            (m for m in _other_branches(p.motors_deg, limits, zones) if path_crosses(here, m, zones, axes) is None),
            None)
        if clear is None:
            dropped.append(SkippedPoint(p.point_id, p.series, p.theta_i_deg, p.phi_i_deg, p.theta_o_deg,
                                        p.phi_o_deg, f"collision:{zone}"))
        else:
            kept.append(replace(p, motors_deg=clear))
            here = clear
    return replace(plan, points=tuple(kept), skipped=plan.skipped + tuple(dropped))


def estimate_rig_time_s(plan: Plan, axes: AxesConfig, capture_s_per_point: float,
                        start_deg: Sequence[float] = START_DEG) -> float:
    """Rig time of the measured points in plan order: moves plus a nominal capture time each."""
    motors = np.array([p.motors_deg for p in plan.points], float).reshape(-1, 4)
    return path_time_s(axes, start_deg, motors) + capture_s_per_point * len(plan.points)


def rig_time_comparison(campaign: Campaign, rig: RigConfig, capture_s_per_point: float = 0.0) -> tuple[float, float]:
    """Estimated rig time (s) of the campaign in table order and in optimised order (`rig plan`).

    With forbidden zones the two orders may leave out different points (collisions depend on the order).
    Both are `build_plan`'s plans; the points and motors are worked out once for the two.
    """
    plan = table_plan(campaign, rig)
    zones = zones_of(rig)
    table, optimised = (_in_order(plan, rig.axes, zones, o) for o in ("table", "optimised"))
    return (estimate_rig_time_s(table, rig.axes, capture_s_per_point),
            estimate_rig_time_s(optimised, rig.axes, capture_s_per_point))
