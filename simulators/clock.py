"""Simulated rig clock: moves and exposures cost rig time, never wall time."""

from __future__ import annotations

import threading

from drivers.interfaces import Clock


class SimClock(Clock):
    """A monotonic clock advanced only by `sleep`; thread-safe."""

    def __init__(self, start_s: float = 0.0):
        self._t = float(start_s)
        self._lock = threading.Lock()

    def now(self) -> float:
        with self._lock:
            return self._t

    def sleep(self, seconds: float) -> None:
        if seconds < 0:
            raise ValueError(f"cannot sleep a negative time ({seconds} s)")
        with self._lock:
            self._t += seconds
