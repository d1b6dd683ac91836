"""Forbidden zones of the rig file: boxes in motor space the axes must never enter
(rig.planning.collisions checks positions and moves against them)."""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field, model_validator

from rig.config.strict import StrictModel
from rig.physics import geometry as geo

Interval = tuple[float, float]


class ForbiddenZone(StrictModel):
    """A box of motor positions the rig must never be in nor pass through (inclusive bounds)."""

    name: str = Field(min_length=1, pattern=r"^[^:\s]+$")
    description: str = ""
    stage_vertical: Interval | None = None
    stage_normal: Interval | None = None
    arm_azimuth: Interval | None = None
    arm_polar: Interval | None = None

    @model_validator(mode="after")
    def _intervals(self):
        given = {n: getattr(self, n) for n in geo.AXIS_NAMES if getattr(self, n) is not None}
        if not given:
            raise ValueError(f"zone {self.name!r} restricts no axis; give at least one of {', '.join(geo.AXIS_NAMES)}")
        for axis, (lo, hi) in given.items():
            if not lo < hi:
                raise ValueError(f"zone {self.name!r}: {axis} must be [low, high] with low < high, got {[lo, hi]}")
        return self

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper bounds (4,) in AXIS_NAMES order; ±inf for unrestricted axes."""
        box = [getattr(self, n) or (-math.inf, math.inf) for n in geo.AXIS_NAMES]
        return np.array([b[0] for b in box], float), np.array([b[1] for b in box], float)


class CollisionsConfig(StrictModel):
    zones: list[ForbiddenZone] = []

    @model_validator(mode="after")
    def _unique_names(self):
        names = [z.name for z in self.zones]
        if len(names) != len(set(names)):
            raise ValueError(f"zone names must be unique, got {names}")
        return self
