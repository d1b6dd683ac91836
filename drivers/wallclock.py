"""Wall clock for real rigs (and for clients of a served simulated rig, which runs faster)."""

from __future__ import annotations

import math
import time

from rig.core.clock import Clock


class WallClock(Clock):
    """`scale` rig seconds pass per wall second: 1 on hardware; a served simulated rig (`rig sim serve
    --speed N`) runs N times faster than wall time, and so does its clients' clock."""

    def __init__(self, scale: float = 1.0):
        if not (math.isfinite(scale) and scale > 0):
            raise ValueError(f"clock scale must be a positive number, got {scale!r}")
        self.scale = scale
        self._origin = time.monotonic()

    def now(self) -> float:
        return (time.monotonic() - self._origin) * self.scale

    def sleep(self, seconds: float) -> None:
        """Until `seconds` of this clock's time have passed, in slices of at most CHECK_SLICE_S of wall time, so
        that `sleep_check` can end a long move's wait, and no longer than the next keep-alive is due. Counted on
        `now()`, so that a clock that stands still for a while (the served world's, rig.simulators.clock) sleeps
        longer by as much."""
        if seconds < 0:
            raise ValueError(f"cannot sleep a negative time ({seconds} s)")
        end = self.now() + seconds
        self._check()
        while (left := end - self.now()) > 0:
            time.sleep(min(left / self.scale, self.CHECK_SLICE_S, self._until_due_s() / self.scale))
            self._check()
