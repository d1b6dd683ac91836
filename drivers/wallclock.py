"""Wall clock for real rigs."""

from __future__ import annotations

import time

from drivers.interfaces import Clock


class WallClock(Clock):
    def now(self) -> float:
        return time.monotonic()

    def sleep(self, seconds: float) -> None:
        time.sleep(seconds)
