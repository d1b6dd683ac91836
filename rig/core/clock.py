"""The time source every wait of a rig goes through."""

from __future__ import annotations

import abc
from collections.abc import Callable


class Clock(abc.ABC):
    """Time source of a rig: wall time on hardware, simulated time in simulators.

    Every wait of a driver (a move, an exposure, a lamp ramp, a retry's back-off) is a
    `sleep` on this clock, so the clock is where a wait can be cut short: the run engine
    installs a `sleep_check` that raises when the operator asked to stop the axes now
    (a second Ctrl+C, SIGTERM). Raising only there, between two device exchanges, never
    tears an exchange in half, and the exit path can still talk to every device.
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
        """Let `seconds` of rig time pass (calling `sleep_check` as documented above)."""

    def _check(self) -> None:
        """Run the installed `sleep_check`, if any (for implementations of `sleep`)."""
        if self.sleep_check is not None:
            self.sleep_check()
