"""The run's source of points for `sampling: {mode: adaptive}`: after the first pass, one batch at a time.

The engine asks for more points whenever its queue runs dry (after the closing E⊥ reading, so every row is
final); `AdaptiveSampler.next_batch` chooses the batch (rig.analysis.adaptive), checks its moves against the
rig's forbidden zones, and logs it to events.jsonl (`adaptive_batch`: its points with their motors, the planned
rig time, the gain and why) before a single one is measured; it returns nothing once the budget or the target
is reached (`sampling_done`, with the reason). A resume (rig.acquisition.resume) puts the logged batches back
into the plan and hands them to the sampler, so the batch in flight is finished and the next one is chosen from
the same rows as without the interruption.

The budget is counted in *planned* rig time after warm-up: the moves in travel order (the axes' speeds and
settling, rig.planning.ordering), a nominal capture per point and an E⊥ reading per batch. Moves dominate the
rig time of this rig (a point's capture takes tens of milliseconds, a move seconds), so the planned time is
close to the real one, and unlike the real one it does not change when a run is resumed.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from rig.acquisition.engine import NOMINAL_CAPTURE_S
from rig.analysis.adaptive import choose_batch
from rig.config.campaign import Campaign
from rig.config.rigfile import RigConfig
from rig.core import events
from rig.planning.candidates import candidate_plan, pattern_ids
from rig.planning.collisions import zones_of
from rig.planning.ordering import START_DEG, path_time_s
from rig.planning.plan import drop_colliding_moves
from rig.planning.points import Motors, Plan, PlannedPoint

#: Planned rig time of one E⊥ reading (a few meter readings of ~0.1 s each).
READING_S = 0.5


def planned_time_s(plan: Plan, rig: RigConfig) -> float:
    """Planned rig time of a plan from the start position: moves, captures, an E⊥ reading per series."""
    motors = np.array([p.motors_deg for p in plan.points], float).reshape(-1, 4)
    return path_time_s(rig.axes, START_DEG, motors) + NOMINAL_CAPTURE_S * len(plan.points) + READING_S * len(
        {p.series for p in plan.points})


class AdaptiveSampler:
    """Chooses an adaptive campaign's batches (module docstring)."""

    def __init__(self, campaign: Campaign, rig: RigConfig, plan: Plan, logged: Sequence[Mapping[str, Any]] = ()):
        """`plan`: the plan the run starts with (a resumed run's holds the logged batches' points too);
        `logged`: the `adaptive_batch` events of a resumed run."""
        self.spec = campaign.sampling
        self.rig = rig
        self.zones = zones_of(rig)
        self.candidates = candidate_plan(campaign, rig)
        self.candidate_ids = {p.point_id for p in self.candidates.points}
        self.pattern = pattern_ids(campaign, self.candidates)
        in_batches = {pid for e in logged for pid in e["points"]}
        first_pass = replace(plan, points=tuple(p for p in plan.points if p.point_id not in in_batches))
        self.planned_s = planned_time_s(first_pass, rig) + sum(float(e["estimated_s"]) for e in logged)
        self.taken = {p.point_id for p in plan.points}
        self.here: Motors = plan.points[-1].motors_deg if plan.points else START_DEG
        self.taken |= {pid for e in logged for pid in e.get("unreachable", [])}
        self.batches = len(logged)
        self.done: str | None = None
        self.loo_cache: dict[bytes, np.ndarray] = {}

    def next_batch(self, rows: Sequence[Mapping[str, object]], event: Callable[..., None]) -> list[PlannedPoint]:
        """The next batch, logged; [] once the campaign is done (logged once, with the reason).

        Its moves start from the last planned point, not from the axes' read-back: the choice must not depend on
        anything a resumed run does differently."""
        if self.done is not None:
            return []
        position = self.here
        spec = self.spec
        left_s = (spec.budget_rig_time_s - self.planned_s) if spec.budget_rig_time_s is not None else np.inf
        batch = choose_batch(rows, self.candidates, self.taken, position, self.rig.axes, self.zones,
                             batch_points=spec.batch_points, capture_s=NOMINAL_CAPTURE_S, reading_s=READING_S,
                             max_s=left_s, pattern=self.pattern, loo_cache=self.loo_cache)
        reason = None
        if batch is None:
            reason = (f"budget reached: {self.planned_s:.0f} s planned of {spec.budget_rig_time_s:g} s, and no batch "
                      f"left fits in the rest" if not self.candidate_ids <= self.taken
                      else "every candidate measured")
        elif spec.target_u_rel is not None and batch.max_u_rel <= spec.target_u_rel:
            reason = f"target reached: largest u/(f+τ) {batch.max_u_rel:.4f} ≤ {spec.target_u_rel:g}"
        if reason is not None or batch is None:
            self.done = reason
            event(events.SAMPLING_DONE, reason=reason, batches=self.batches, planned_rig_time_s=self.planned_s)
            return []
        checked = drop_colliding_moves(Plan((), batch.points, ()), self.rig.axes, self.zones, position)
        kept, unreachable = list(checked.points), [s.point_id for s in checked.skipped]
        estimated = self._estimate(kept, position)
        self.planned_s += estimated
        self.taken |= {p.point_id for p in kept} | set(unreachable)
        self.here = kept[-1].motors_deg if kept else self.here
        self.batches += 1
        event(events.ADAPTIVE_BATCH, batch=self.batches, series=batch.series, points=[p.point_id for p in kept],
              motors_deg=[list(p.motors_deg) for p in kept], unreachable=unreachable, estimated_s=estimated,
              planned_rig_time_s=self.planned_s, gain=batch.gain, score_per_s=batch.score_per_s,
              max_u_rel=batch.max_u_rel,
              why=f"largest expected error removed per second: Δθi·Σ(u/(f+τ))² {batch.gain:.3g} over "
                  f"{estimated:.0f} s at series {batch.series} ({len(kept)} views, calibrated u)")
        return kept

    def _estimate(self, points: Sequence[PlannedPoint], position: Motors) -> float:
        motors = np.array([p.motors_deg for p in points], float).reshape(-1, 4)
        return path_time_s(self.rig.axes, position, motors) + NOMINAL_CAPTURE_S * len(points) + READING_S


def sampler_for(campaign: Campaign, rig: RigConfig, plan: Plan,
                logged: Sequence[Mapping[str, Any]] = ()) -> AdaptiveSampler | None:
    """The run's point source: an AdaptiveSampler for `sampling: {mode: adaptive}`, else None (the plan is all)."""
    return AdaptiveSampler(campaign, rig, plan, logged) if campaign.sampling.mode == "adaptive" else None
