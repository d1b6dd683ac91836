"""The time source every wait of a rig goes through."""

from __future__ import annotations

import abc
import math
import threading
from collections.abc import Callable
from dataclasses import dataclass


@dataclass
class _KeepAlive:
    period_s: float
    callback: Callable[[], None]
    due_s: float


class Clock(abc.ABC):
    """Time source of a rig: wall time on hardware, simulated time in simulators.

    Every wait of a driver (a move, an exposure, a lamp ramp, a retry's back-off) is a
    `sleep` on this clock, so the clock is where a wait can be cut short: the run engine
    installs a `sleep_check` that raises when the operator asked to stop the axes now
    (a second Ctrl+C, SIGTERM). Raising only there, between two device exchanges, never
    tears an exchange in half, and the exit path can still talk to every device.

    For the same reason a sleep is where keep-alives run (`keep_alive`): a device with a
    communication watchdog (the lamp supply) is fed between two slices of a long wait, on
    the sleeping thread, so its exchange never interleaves with another on the same link,
    and on a simulated clock it is fed in rig time however fast rig time passes.
    """

    #: Called when a sleep starts and at least every `CHECK_SLICE_S` of wall time while it lasts;
    #: whatever it raises ends the sleep. None: sleeps are never cut short.
    sleep_check: Callable[[], None] | None = None
    #: Wall time between two calls of `sleep_check` during one sleep.
    CHECK_SLICE_S = 0.05

    @abc.abstractmethod
    def now(self) -> float:
        """Seconds since an arbitrary, fixed origin."""

    @abc.abstractmethod
    def sleep(self, seconds: float) -> None:
        """Let `seconds` of rig time pass (calling `sleep_check` and due keep-alives as documented above)."""

    # -- keep-alives --------------------------------------------------------------------------
    def keep_alive(self, period_s: float, callback: Callable[[], None]) -> Callable[[], None]:
        """Call `callback` during sleeps whenever `period_s` of rig time has passed since its last call
        (or since now); returns the function that cancels it. The callback handles its own device
        errors: whatever it raises ends the sleep like `sleep_check`."""
        if not (math.isfinite(period_s) and period_s > 0):
            raise ValueError(f"keep-alive period must be a positive number of seconds, got {period_s!r}")
        entry = _KeepAlive(period_s, callback, self.now() + period_s)
        with self._keep_alive_lock():
            self.__dict__.setdefault("_keep_alives", []).append(entry)

        def cancel() -> None:
            with self._keep_alive_lock():
                entries = self.__dict__.get("_keep_alives", [])
                if entry in entries:
                    entries.remove(entry)
        return cancel

    def _keep_alive_lock(self) -> threading.Lock:
        lock: threading.Lock = self.__dict__.setdefault("_keep_alive_guard", threading.Lock())
        return lock

    def _until_due_s(self) -> float:
        """Rig time until the next keep-alive is due (0 if one is overdue, inf without any)."""
        entries = self.__dict__.get("_keep_alives")
        if not entries:
            return math.inf
        return max(min(e.due_s for e in entries) - self.now(), 0.0)

    def _check(self) -> None:
        """Run the due keep-alives, then the installed `sleep_check` (for implementations of `sleep`)."""
        entries = self.__dict__.get("_keep_alives")
        if entries and not self.__dict__.get("_feeding"):
            now = self.now()
            due = [e for e in list(entries) if e.due_s <= now]
            self.__dict__["_feeding"] = True          # a keep-alive that waits must not feed itself
            try:
                for entry in due:
                    entry.due_s = now + entry.period_s
                    entry.callback()
            finally:
                self.__dict__["_feeding"] = False
        if self.sleep_check is not None:
            self.sleep_check()
