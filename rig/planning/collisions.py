"""Forbidden zones in motor space, and the moves and positions that would enter them.

A zone is a box in the four motor angles (degrees, as commanded, not wrapped:
the same coordinates as the soft limits); an axis left out is unrestricted.
Example, the camera arm through the lamp lever:

    collisions:
      zones:
        - name: lamp_lever
          description: camera arm through the lamp lever
          arm_azimuth: [-100, -80]
          arm_polar: [80, 100]

Moves are checked along the path the axes really take: all four start together,
each with its own trapezoidal profile (rig.core.motion.position_at), so the path is
not a straight line in motor space when the durations differ. It is sampled in
time so that no axis moves more than SAMPLE_STEP_DEG between samples: a path
can only cut a corner of a zone by less than that without being caught, so give
zones that much margin.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from rig.config.zones import ForbiddenZone
from rig.core.motion import move_time_s, position_at
from rig.physics import geometry as geo

if TYPE_CHECKING:
    from rig.config.rigfile import AxesConfig, RigConfig

#: Largest step of any axis between two checked positions of a move, degrees.
SAMPLE_STEP_DEG = 0.1


def zones_of(rig: RigConfig) -> tuple[ForbiddenZone, ...]:
    """The rig's forbidden zones."""
    return tuple(rig.collisions.zones)


def zone_at(positions_deg: np.ndarray, zones: Sequence[ForbiddenZone]) -> np.ndarray:
    """Name of the first zone containing each position (..., 4), "" where none (or NaN)."""
    positions = np.asarray(positions_deg, float)
    names = np.full(positions.shape[:-1], "", dtype=object)
    for zone in reversed(zones):              # the first zone in the configuration wins
        lo, hi = zone.bounds()
        names[np.all((positions >= lo) & (positions <= hi), axis=-1)] = zone.name
    return names


def move_positions(axes: AxesConfig, start_deg: Sequence[float] | np.ndarray,
                   target_deg: Sequence[float] | np.ndarray) -> np.ndarray:
    """Positions (m, 4) along a simultaneous move, sampled in time, end points included."""
    cfg = [getattr(axes, n) for n in geo.AXIS_NAMES]
    speed = np.array([c.speed_deg_s for c in cfg])
    duration = float(np.max(move_time_s(np.subtract(target_deg, start_deg), speed, [c.accel_deg_s2 for c in cfg])))
    fastest = float(np.max(speed))
    times = np.linspace(0.0, duration, max(2, math.ceil(duration * fastest / SAMPLE_STEP_DEG) + 1))
    return np.array([[position_at(s, t, tau, c.speed_deg_s, c.accel_deg_s2)
                      for s, t, c in zip(start_deg, target_deg, cfg)] for tau in times])


def path_crosses(start_deg: Sequence[float], target_deg: Sequence[float], zones: Sequence[ForbiddenZone],
                 axes: AxesConfig) -> str | None:
    """Name of the first zone the move enters (end points included), or None.

    Each axis moves monotonically, so only zones that overlap the box spanned by
    start and target need the sampled path.
    """
    start, target = np.asarray(start_deg, float), np.asarray(target_deg, float)
    low, high = np.minimum(start, target), np.maximum(start, target)
    boxes = [(z, *z.bounds()) for z in zones]
    near = [z for z, lo, hi in boxes if np.all((lo <= high) & (hi >= low))]
    if not near:
        return None
    hits = zone_at(move_positions(axes, start, target), near)
    inside = hits != ""
    return str(hits[np.argmax(inside)]) if inside.any() else None

