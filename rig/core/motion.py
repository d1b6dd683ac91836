"""Trapezoidal motion profile of one axis (pure): the one model of move time, used by the plan's estimates and
ordering, the collision check, the engine's timeouts, the Modbus driver and the simulator."""

from __future__ import annotations

import math
from typing import overload

import numpy as np
from numpy.typing import ArrayLike


@overload
def move_time_s(distance_deg: float, speed_deg_s: float, accel_deg_s2: float) -> float: ...
@overload
def move_time_s(distance_deg: np.ndarray, speed_deg_s: ArrayLike, accel_deg_s2: ArrayLike) -> np.ndarray: ...
def move_time_s(distance_deg: ArrayLike, speed_deg_s: ArrayLike, accel_deg_s2: ArrayLike) -> float | np.ndarray:
    """Duration of rest-to-rest moves with a trapezoidal (or triangular) speed profile.

    Vectorised: the arguments broadcast (the ordering's cost matrices); scalars give a scalar
    (a float), computed without numpy: the simulator and the collision check call this per
    sample, where numpy's per-call overhead made the simulated rig's Modbus exchanges ~25 % slower.
    """
    if isinstance(distance_deg, (int, float)) and isinstance(speed_deg_s, (int, float)) \
            and isinstance(accel_deg_s2, (int, float)):
        dist = abs(distance_deg)
        if dist * accel_deg_s2 < speed_deg_s ** 2:      # never reaches full speed
            return 2.0 * math.sqrt(dist / accel_deg_s2)
        return dist / speed_deg_s + speed_deg_s / accel_deg_s2
    d = np.abs(np.asarray(distance_deg, float))
    speed, accel = np.asarray(speed_deg_s, float), np.asarray(accel_deg_s2, float)
    with np.errstate(invalid="ignore"):
        t = np.where(d * accel < speed ** 2, 2.0 * np.sqrt(d / accel), d / speed + speed / accel)
    return t if t.ndim else float(t)


def position_at(start_deg: float, target_deg: float, elapsed_s: float,
                speed_deg_s: float, accel_deg_s2: float) -> float:
    """Position `elapsed_s` after the start of a rest-to-rest move."""
    d = target_deg - start_deg
    total = move_time_s(d, speed_deg_s, accel_deg_s2)
    if elapsed_s >= total or d == 0.0:
        return target_deg
    sign = math.copysign(1.0, d)
    v_peak = min(speed_deg_s, math.sqrt(abs(d) * accel_deg_s2))
    t_acc = v_peak / accel_deg_s2
    if elapsed_s < t_acc:
        s = 0.5 * accel_deg_s2 * elapsed_s ** 2
    elif elapsed_s < total - t_acc:
        s = 0.5 * accel_deg_s2 * t_acc ** 2 + v_peak * (elapsed_s - t_acc)
    else:
        s = abs(d) - 0.5 * accel_deg_s2 * (total - elapsed_s) ** 2
    return start_deg + sign * s
