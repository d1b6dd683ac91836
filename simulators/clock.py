"""Simulated rig clock: moves and exposures cost rig time, never wall time (unless paced).

A paced clock also lets wall time pass, `pace` wall seconds per rig second, so that
something outside the run (a Ctrl+C, a test's thread) can act while the run is in a
long wait such as the lamp warm-up. `rig run` on the simulated rig takes the pace from
the environment variable RIG_SIM_PACE (default 0: as fast as possible); e.g.
`RIG_SIM_PACE=0.01` makes the 300 s warm-up last 3 s.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections.abc import Iterator
from contextlib import contextmanager

from rig.core.clock import Clock
from rig.drivers.wallclock import WallClock

#: Environment variable with the default pace of new SimClocks (wall seconds per rig second).
PACE_ENV = "RIG_SIM_PACE"


def pace_from_env() -> float:
    """The pace RIG_SIM_PACE asks for (0 when unset); ValueError naming the variable when it is not ≥ 0."""
    text = os.environ.get(PACE_ENV, "").strip()
    if not text:
        return 0.0
    try:
        pace = float(text)
    except ValueError:
        pace = math.nan
    if not (math.isfinite(pace) and pace >= 0):
        raise ValueError(f"environment variable {PACE_ENV}={text!r}: must be a number ≥ 0 "
                         "(wall seconds per simulated rig second)")
    return pace


class SimClock(Clock):
    """A monotonic clock advanced only by `sleep`; thread-safe.

    With `pace` > 0 a sleep also waits `pace` × its rig time of wall time, in slices of
    at most CHECK_SLICE_S, and rig time advances slice by slice. Sleeps keep wall time in
    step with rig time, so the many tiny sleeps of exchanges and exposures cost no extra
    wall time for their number; wall time spent computing (more than one slice behind)
    is not made up by rushing rig time. `pace` None: from RIG_SIM_PACE.
    """

    def __init__(self, start_s: float = 0.0, pace: float | None = None):
        self._t = float(start_s)
        self._lock = threading.Lock()
        self.pace = pace_from_env() if pace is None else pace
        if not (math.isfinite(self.pace) and self.pace >= 0):
            raise ValueError(f"SimClock pace must be a number ≥ 0, got {self.pace}")
        self._wall0, self._t0 = time.monotonic(), self._t

    def now(self) -> float:
        with self._lock:
            return self._t

    def advance(self, seconds: float) -> None:
        """Rig time an instrument spends while its client waits for the reply (`SimWorld.spend_s`):
        no keep-alives, no stop check, no pacing."""
        if seconds < 0:
            raise ValueError(f"cannot advance a negative time ({seconds} s)")
        with self._lock:
            self._t += seconds

    def sleep(self, seconds: float) -> None:
        """Advance rig time by `seconds`, in steps that end where a keep-alive is due (and, paced, in
        wall slices of CHECK_SLICE_S), running the due keep-alives and `sleep_check` after each."""
        if seconds < 0:
            raise ValueError(f"cannot sleep a negative time ({seconds} s)")
        self._check()
        left = seconds
        while left > 0:
            step = min(left, self._until_due_s())
            if self.pace > 0:
                step = min(step, self.CHECK_SLICE_S / self.pace)
            step = max(step, min(left, 1e-9))        # an overdue keep-alive is run below; never stand still
            with self._lock:
                self._t += step
                delay = self._wall0 + (self._t - self._t0) * self.pace - time.monotonic() if self.pace else 0.0
                if delay < -self.CHECK_SLICE_S:     # wall time went on computing: do not race to catch up
                    self._wall0, self._t0, delay = time.monotonic(), self._t, 0.0
            left -= step
            if delay > 0:
                time.sleep(delay)
            self._check()


class ServedClock(WallClock):
    """The served world's clock (`rig sim serve --speed N`): `N` rig seconds per wall second, standing still
    while the world computes (`computing`).

    The world serves clients in other processes, so it runs on wall time; but the wall time it spends rendering a
    frame is no rig time of a real camera, whose frame costs its exposure and readout (which the camera model
    charges). Counted, it would pass `N` times over while the client waits for the frame: at speed 200 a 30 ms
    render is 6 rig s, longer than the lamp supply's communication watchdog, which switched the lamp off before
    every frame of `rig calibrate geometry`'s lamp views. Every peer sees the world's time stand still meanwhile,
    as in the in-process world, where computing costs no rig time either.
    """

    def __init__(self, scale: float = 1.0):
        super().__init__(scale)
        self._lock = threading.Lock()
        self._held_since: float | None = None     # wall time the current hold began (holds may nest)
        self._holds = 0
        self._held_s = 0.0                         # wall time held before the current hold

    def now(self) -> float:
        with self._lock:
            wall = time.monotonic() if self._held_since is None else self._held_since
            return (wall - self._origin - self._held_s) * self.scale

    @contextmanager
    def computing(self) -> Iterator[None]:
        """Rig time stands still for the duration."""
        with self._lock:
            if self._holds == 0:
                self._held_since = time.monotonic()
            self._holds += 1
        try:
            yield
        finally:
            with self._lock:
                self._holds -= 1
                if self._holds == 0 and self._held_since is not None:
                    self._held_s += time.monotonic() - self._held_since
                    self._held_since = None
