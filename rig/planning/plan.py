"""Campaign → plan: incidence series, viewing directions, motor angles, skipped points.

A plan is data. Every planned direction gets a stable `point_id`
(`<series>-<view>`, from the campaign alone) whether it is measured or
skipped, so ids survive a resume and skipped points can be reported. The
order is the campaign's (`table`) or a travel-time optimised one
(`optimised`, rig.planning.ordering); both are deterministic, so a resume that rebuilds
the plan gets the same order. Moves through the rig's forbidden zones
(rig.planning.collisions) are checked in the final order. The work grows linearly with
the points (tests/planning/test_plan_scaling.py counts it): nothing scans all points per
series, repeated views are found with a k-d tree, and the ordering goes block by block.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from typing import Literal

import numpy as np
from scipy.spatial import cKDTree

from rig.config.campaign import Campaign, CentredPattern
from rig.config.rigfile import AxesConfig, RigConfig, camera_optics
from rig.config.zones import ForbiddenZone
from rig.physics import geometry as geo
from rig.physics.optics import roi_inside_spot
from rig.planning.collisions import path_crosses, zone_at, zones_of
from rig.planning.ordering import START_DEG, arm_branches, order_plan, path_time_s
from rig.planning.points import Motors, Plan, PlannedPoint, Series, SkippedPoint, as_motors

#: Directions closer than this (radians) are the same planned direction.
SAME_DIRECTION_RAD = 1e-9

Ordering = Literal["optimised", "table"]


def incidence_series(campaign: Campaign) -> list[Series]:
    """Table 1 order: one series per (θi, φi), duplicates removed."""
    seen: set[tuple[float, float]] = set()
    out: list[Series] = []
    for entry in campaign.incidence:
        for theta in entry.theta:
            phi = float(geo.wrap_360(entry.phi))
            key = (round(theta, 9), round(phi, 9) if theta > 0 else 0.0)
            if key not in seen:
                seen.add(key)
                out.append(Series(len(out), float(theta), phi))
    return out


def viewing_directions(campaign: Campaign, theta_i_deg: float, phi_i_deg: float) -> np.ndarray:
    """Union of the campaign's viewing patterns for one incidence, SCS unit vectors (M, 3).

    Order: patterns in file order, θ-major within a pattern; repeats removed.
    """
    wi = geo.sph_to_vec(np.radians(theta_i_deg), np.radians(phi_i_deg))
    centres = {"incidence": wi, "mirror": geo.mirror_direction(wi), "normal": np.array([0.0, 0.0, 1.0])}
    chunks = []
    for spec in campaign.viewing:
        if isinstance(spec, CentredPattern):
            th, ph = np.meshgrid(np.radians(spec.theta), np.radians(spec.phi), indexing="ij")
            chunks.append(geo.centre_pattern(th.ravel(), ph.ravel(), centres[spec.centred_on]))
        else:
            pts = np.radians(np.asarray(spec.points, float))
            chunks.append(geo.sph_to_vec(pts[:, 0], pts[:, 1]))
    dirs = np.concatenate(chunks)
    return dirs[_first_of_repeats(dirs)]


def _first_of_repeats(dirs: np.ndarray) -> np.ndarray:
    """Indices of the unit vectors (n, 3) kept in order: each unless an earlier kept one lies within
    SAME_DIRECTION_RAD of it.

    Only the pairs a k-d tree finds closer than a chord of twice that angle are measured (a chord
    never exceeds its angle), so a dense viewing pattern costs O(n log n), not the n² angles of all pairs.
    """
    pairs = cKDTree(dirs).query_pairs(2 * SAME_DIRECTION_RAD, output_type="ndarray")
    pairs = pairs[geo.angle_between(dirs[pairs[:, 0]], dirs[pairs[:, 1]]) <= SAME_DIRECTION_RAD]
    keep = np.ones(len(dirs), bool)
    for earlier, later in sorted(map(tuple, pairs), key=lambda pair: pair[1]):     # i < j per pair
        if keep[earlier]:
            keep[later] = False
    return np.flatnonzero(keep)


def build_plan(campaign: Campaign, rig: RigConfig, ordering: Ordering | None = None) -> Plan:
    """Plan every (incidence, view) pair; leave out, with a reason, what cannot be measured.

    `ordering`: `table` (campaign order) or `optimised` (least rig time);
    default the campaign's `ordering`, else optimised.
    """
    ordering = ordering or getattr(campaign, "ordering", "optimised")
    if ordering not in ("optimised", "table"):
        raise ValueError(f"ordering must be 'optimised' or 'table', got {ordering!r}")
    return _in_order(_table_plan(campaign, rig), rig.axes, zones_of(rig), ordering)


def _in_order(plan: Plan, axes: AxesConfig, zones: Sequence[ForbiddenZone], ordering: Ordering) -> Plan:
    """The table plan in `ordering`, with the moves that would cross a forbidden zone checked."""
    if ordering == "optimised":
        plan = order_plan(plan, axes, zones, START_DEG)
    return drop_colliding_moves(plan, axes, zones, START_DEG)


def _table_plan(campaign: Campaign, rig: RigConfig) -> Plan:
    """Every point in campaign order with its motors, or skipped with a reason; moves not yet checked."""
    limits = rig.axes.limits()
    zones = zones_of(rig)
    optics = camera_optics(rig)
    geometry = rig.geometry
    occlusion_rad = np.arctan2(geometry.lamp_housing_radius_m, geometry.lamp_distance_m)
    max_view_rad = np.radians(campaign.limits.max_view_theta_deg)
    current = START_DEG
    series_list = incidence_series(campaign)
    points: list[PlannedPoint] = []
    skipped: list[SkippedPoint] = []
    for series in series_list:
        wi = geo.sph_to_vec(np.radians(series.theta_i_deg), np.radians(series.phi_i_deg))
        wo = viewing_directions(campaign, series.theta_i_deg, series.phi_i_deg)
        theta_o, phi_o = geo.vec_to_sph(wo)
        theta_o_deg, phi_o_deg = np.degrees(theta_o), np.degrees(phi_o)
        motors = geo.inverse_deg(series.theta_i_deg, series.phi_i_deg, theta_o_deg, phi_o_deg,
                                 limits, current).as_array()
        motors, zone = _outside_zones(motors, limits, zones)
        reason = np.full(len(wo), "", dtype=object)
        _mark(reason, wo[:, 2] <= 1e-12, "below_horizon")
        _mark(reason, theta_o > max_view_rad + 1e-12, "beyond_max_view_theta")
        _mark(reason, geo.angle_between(wo, wi[None, :]) < occlusion_rad, "occluded_by_lamp")
        _mark(reason, ~np.all(np.isfinite(motors), axis=1), "axis_limits")
        _mark(reason, zone != "", "forbidden_zone:" + zone)
        if campaign.limits.skip_roi_unlit:
            ok = np.all(np.isfinite(motors), axis=1)
            lit = np.zeros(len(wo), bool)
            if ok.any():
                m = np.radians(motors[ok])
                lit[ok] = roi_inside_spot(m[:, 0], m[:, 1], m[:, 2], m[:, 3], campaign.capture.roi_px,
                                          optics, geometry.spot_diameter_m / 2)
            _mark(reason, ~lit, "roi_unlit")

        for k in range(len(wo)):
            pid = f"{series.index:02d}-{k:03d}"
            angles = (series.theta_i_deg, series.phi_i_deg, float(theta_o_deg[k]), float(phi_o_deg[k]))
            if reason[k]:
                skipped.append(SkippedPoint(pid, series.index, *angles, reason[k]))
            else:
                points.append(PlannedPoint(pid, series.index, *angles, as_motors(motors[k])))
        if np.any(reason == ""):                # the next series' inverse kinematics starts at its last point
            current = points[-1].motors_deg
    return Plan(tuple(series_list), tuple(points), tuple(skipped))


def _mark(reason: np.ndarray, mask: np.ndarray, why: str | np.ndarray) -> None:
    """Give the points in `mask` that have no skip reason yet the reason `why` (the first reason wins)."""
    free = (reason == "") & mask
    reason[free] = np.broadcast_to(np.asarray(why, dtype=object), reason.shape)[free]


def _outside_zones(motors: np.ndarray, limits: geo.AxisLimits,
                   zones: Sequence[ForbiddenZone]) -> tuple[np.ndarray, np.ndarray]:
    """Motors (n, 4) moved to the other arm branch where they lie in a forbidden zone and that one is
    usable; and the zone (or "") each final position lies in."""
    zone = zone_at(motors, zones)
    twins = arm_branches(motors, limits, zones)[:, 1:]
    usable = np.all(np.isfinite(twins), axis=-1)
    move = (zone != "") & usable.any(axis=1)
    first = twins[np.arange(len(motors)), np.argmax(usable, axis=1)]
    return np.where(move[:, None], first, motors), np.where(move, "", zone)


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
    plan = _table_plan(campaign, rig)
    zones = zones_of(rig)
    table, optimised = (_in_order(plan, rig.axes, zones, o) for o in ("table", "optimised"))
    return (estimate_rig_time_s(table, rig.axes, capture_s_per_point),
            estimate_rig_time_s(optimised, rig.axes, capture_s_per_point))
