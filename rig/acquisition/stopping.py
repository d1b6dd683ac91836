"""The operator's stop requests, as flags the engine looks at where it may stop.

A graceful stop (first Ctrl+C) is honoured by every wait of the engine, which sleeps in
slices of at most `StopRequests.CHECK_S` of rig time, and between points, never inside one.
An abort (second Ctrl+C, SIGTERM) is honoured by any sleep of the rig clock, even inside a
move. Requests only set a flag: they are safe from a signal handler or another thread.
"""

from __future__ import annotations

from collections.abc import Callable

from rig.core.clock import Clock


class StopRequested(Exception):
    """A graceful stop (first Ctrl+C): raised by a wait of the engine or between points, never inside one."""


class AbortRequested(BaseException):
    """Stop the axes now (second Ctrl+C, SIGTERM): raised by any sleep of the rig clock or between points.

    A BaseException like KeyboardInterrupt, so that no `except Exception` on its way (a driver's
    retry, a suspender's probe) takes it for a device fault.
    """


class StopRequests:
    """Stop and abort flags, and the waits that honour them."""

    #: Longest rig time (s) between two looks at the stop request while the engine waits.
    CHECK_S = 1.0

    def __init__(self, clock: Clock, on_first_stop: Callable[[str], None]):
        """`on_first_stop(reason)`: called once, when a stop request is first honoured (to log it)."""
        self.clock = clock
        self.on_first_stop = on_first_stop
        self.stop_reason: str | None = None        # finish the point, park
        self.abort_reason: str | None = None       # stop the axes now
        self._stop_honoured = False

    @property
    def reason(self) -> str | None:
        """Why the run is being stopped: the abort's reason before the stop's."""
        return self.abort_reason or self.stop_reason

    def request_stop(self, reason: str) -> None:
        if self.stop_reason is None:
            self.stop_reason = reason

    def request_abort(self, reason: str) -> None:
        if self.abort_reason is None:
            self.abort_reason = reason

    def check_abort(self) -> None:
        """The clock's sleep check: an abort ends any sleep, even a move's."""
        if self.abort_reason is not None:
            raise AbortRequested(self.abort_reason)

    def check_stop(self) -> None:
        """Raise AbortRequested or StopRequested if asked."""
        self.check_abort()
        if self.stop_reason is None:
            return
        if not self._stop_honoured:
            self._stop_honoured = True
            self.on_first_stop(self.stop_reason)
        raise StopRequested(self.stop_reason)

    def wait(self, seconds: float) -> None:
        """Let `seconds` of rig time pass, looking at the requests at least every CHECK_S."""
        left = seconds
        self.check_stop()
        while left > 0:
            step = min(left, self.CHECK_S)
            self.clock.sleep(step)
            left -= step
            self.check_stop()
