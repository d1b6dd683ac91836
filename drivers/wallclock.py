"""Wall clock for real rigs."""

from __future__ import annotations

import time

from rig.core.clock import Clock


class WallClock(Clock):
    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        """Sleep in slices of at most CHECK_SLICE_S, so that `sleep_check` can end a long move's wait."""
        if seconds < 0:
            raise ValueError(f"cannot sleep a negative time ({seconds} s)")
        end = time.monotonic() + seconds
        self._check()
        while (left := end - time.monotonic()) > 0:
            time.sleep(min(left, self.CHECK_SLICE_S))
            self._check()
