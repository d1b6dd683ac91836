"""What a plan is made of: incidence series, planned and skipped points, and why a point is skipped.

Plain frozen data (a plan is data): rig.planning.plan builds it, rig.planning.ordering reorders
it, the engine measures it and the dataset records its skipped points.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Protocol

#: The four motor angles of a position, degrees: stage_vertical, stage_normal, arm_azimuth, arm_polar.
Motors = tuple[float, float, float, float]

SKIP_REASONS = {
    "below_horizon": "viewing direction at or below the sample plane (θo ≥ 90°)",
    "beyond_max_view_theta": "θo beyond limits.max_view_theta_deg",
    "occluded_by_lamp": "camera would look into the lamp housing (too close to retroreflection)",
    "axis_limits": "no axis solution inside the configured limits",
    "roi_unlit": "the ROI would not lie entirely inside the lit spot",
    "forbidden_zone": "the axes would stand inside a forbidden zone of the rig (on every arm branch)",
    "collision": "the move to it from the previous point kept would cross a forbidden zone of the rig",
}


def as_motors(values: Iterable[float]) -> Motors:
    """Four motor angles (a row of an array) as plain floats."""
    a, b, c, d = (float(x) for x in values)
    return a, b, c, d


def describe_reason(reason: str) -> str:
    """Text of a skip reason; `forbidden_zone:<zone>` and `collision:<zone>` name the zone."""
    kind, _, zone = reason.partition(":")
    return SKIP_REASONS[kind] + (f": {zone}" if zone else "")


@dataclass(frozen=True)
class Series:
    index: int
    theta_i_deg: float
    phi_i_deg: float


@dataclass(frozen=True)
class PointAngles:
    """A planned direction pair: its stable id, series and requested BRDF angles (degrees)."""

    point_id: str
    series: int
    theta_i_deg: float
    phi_i_deg: float
    theta_o_deg: float
    phi_o_deg: float


@dataclass(frozen=True)
class PlannedPoint(PointAngles):
    motors_deg: Motors


@dataclass(frozen=True)
class SkippedPoint(PointAngles):
    reason: str


@dataclass(frozen=True)
class Plan:
    series: tuple[Series, ...]
    points: tuple[PlannedPoint, ...]
    skipped: tuple[SkippedPoint, ...]

    @property
    def n_planned(self) -> int:
        return len(self.points) + len(self.skipped)

    def skipped_by_reason(self) -> dict[str, int]:
        return dict(Counter(s.reason for s in self.skipped))


class PointSource(Protocol):
    """Where a run gets points beyond its plan (an adaptive campaign: rig.session.adaptive_sampler)."""

    def next_batch(self, rows: Sequence[Mapping[str, object]], event: Callable[..., None]) -> Sequence[PlannedPoint]:
        """More points to measure given the rows so far (all final), to be measured after the plan's points in
        plan order; none when the run is done. `event(kind, **fields)` logs to the run's events.jsonl."""
        ...
