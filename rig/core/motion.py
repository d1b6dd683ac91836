"""Trapezoidal motion profile of one axis (pure): used by plan estimates and the simulator."""

from __future__ import annotations

import math


def move_time_s(distance_deg: float, speed_deg_s: float, accel_deg_s2: float) -> float:
    """Duration of a rest-to-rest move with a trapezoidal (or triangular) speed profile."""
    d = abs(distance_deg)
    if d * accel_deg_s2 < speed_deg_s ** 2:      # never reaches full speed
        return 2.0 * math.sqrt(d / accel_deg_s2)
    return d / speed_deg_s + speed_deg_s / accel_deg_s2


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
