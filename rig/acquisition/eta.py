"""The run's ETA in rig time: the lamp's warm-up still to come, and the plan's estimate of the points left,
corrected as the run goes.

Each point's estimate is the plan's move to it from its predecessor plus a nominal capture;
the points left take their estimate × (rig time measuring / estimate of the points done). The warm-up
counts with the run's expectation (rig.planning.estimate) until it starts, then with the rest the warm-up
itself reports (rig.acquisition.warmup), then not at all.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Iterable

import numpy as np

from rig.config.rigfile import AxesConfig
from rig.planning.ordering import travel_time_s
from rig.planning.points import Plan


def point_estimates_s(plan: Plan, start_deg: Iterable[float], axes: AxesConfig, capture_s: float) -> dict[str, float]:
    """The plan's rig time of each point: the move from its predecessor in plan order (the
    first: from `start_deg`) plus `capture_s`."""
    path = np.array([tuple(start_deg), *(p.motors_deg for p in plan.points)], float)
    moves = travel_time_s(axes, path[:-1], path[1:])
    return {p.point_id: float(t) + capture_s for p, t in zip(plan.points, moves)}


class Eta:
    """Estimated rig time left; the engine says when it measures and which points are done or undone."""

    def __init__(self, rig_time_s: Callable[[], float], warmup_s: float = 0.0):
        """No estimate of the points until `plan` gives one (it needs the axes' position, and reading it may
        already report a driver's retry with the ETA); `warmup_s`: the warm-up the run expects."""
        self.rig_time_s = rig_time_s
        self.warmup_expected_s = self.warmup_left_s = warmup_s
        #: Where the run is, for the words of a stop request: starting, warm-up, measuring or between.
        self.stage = "starting"
        self.estimates_s: dict[str, float] = {}
        self.left_estimate_s = self.done_estimate_s = 0.0
        self.active_s = 0.0                       # rig time measuring, without warm-up and pauses
        self.active_since: float | None = None    # rig time the present stretch of measuring began

    def plan(self, estimates_s: dict[str, float], done_ids: Collection[str]) -> None:
        """The estimate of each point, and which are done already (a resume)."""
        self.estimates_s = estimates_s
        self.left_estimate_s = sum(t for pid, t in estimates_s.items() if pid not in done_ids)

    def warming(self, left_s: float) -> None:
        """The warm-up goes on, with `left_s` expected (0: it ended)."""
        self.warmup_left_s = max(left_s, 0.0)
        self.stage = "warm-up" if left_s > 0 else "between"

    def measuring(self, active: bool) -> None:
        """Start (True) or end (False) a stretch of rig time that counts as measuring."""
        self.stage = "measuring" if active else "between"
        now = self.rig_time_s()
        if self.active_since is not None:
            self.active_s += now - self.active_since
        self.active_since = now if active else None

    def add(self, estimates_s: dict[str, float]) -> None:
        """Points added to the plan while the run goes (an adaptive campaign's batch)."""
        self.estimates_s.update(estimates_s)
        self.left_estimate_s += sum(estimates_s.values())

    def done(self, point_id: str) -> None:
        self.done_estimate_s += self.estimates_s[point_id]
        self.left_estimate_s -= self.estimates_s[point_id]

    def undone(self, point_ids: Iterable[str]) -> None:
        """Points discarded: they are left again (their measuring time stays in the rate)."""
        self.left_estimate_s += sum(self.estimates_s[pid] for pid in point_ids)

    def left_s(self) -> float:
        """Rig time (s) left: the warm-up's rest, and the points left at their plan estimate × (measured /
        estimated) so far.

        Warm-up and pauses are not measuring time, so they do not inflate the rate; E⊥ readings,
        darks and retries between points do, as they will recur.
        """
        active = self.active_s + (self.rig_time_s() - self.active_since if self.active_since is not None else 0.0)
        rate = active / self.done_estimate_s if self.done_estimate_s > 0 and active > 0 else 1.0
        return self.warmup_left_s + self.left_estimate_s * rate
