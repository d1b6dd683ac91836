"""Retries with back-off, for transient device errors only: the one retry policy of every driver.

A transient fault (timeout, garbled reply, dropped link) costs a retry, after
an optional reconnect, and an event; anything else, or a fault that outlasts
the attempts, propagates as a persistent DeviceError. `RetryingDevice` is the
only place a driver meets this policy, so every driver retries, reconnects and
reports the same way.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, TypeVar

from rig.core import events
from rig.core.clock import Clock
from rig.core.errors import DeviceError

T = TypeVar("T")

#: `events(kind, **fields)`: where drivers report retries, reconnects and errors met while switching off.
EventSink = Callable[..., None]


def no_events(kind: str, **fields: Any) -> None:
    """Default event sink: drivers report retries and reconnects; nobody listens."""


@dataclass(frozen=True)
class RetryPolicy:
    attempts: int = 3
    backoff_s: float = 0.05      # first wait; doubles each time
    max_backoff_s: float = 2.0


DEFAULT_RETRY = RetryPolicy()


def call_with_retry(action: Callable[[], T], *, device: str, what: str, clock: Clock, policy: RetryPolicy,
                    on_retry: EventSink, reconnect: Callable[[], None] | None = None) -> T:
    """Run `action`; on a transient DeviceError wait, reconnect and try again, up to policy.attempts."""
    wait = policy.backoff_s
    for attempt in range(1, policy.attempts + 1):
        try:
            return action()
        except DeviceError as exc:
            if not exc.transient or attempt == policy.attempts:
                if exc.transient:
                    raise DeviceError(device, f"{what} failed {policy.attempts} times; last: {exc}",
                                      unanswered=True) from exc
                raise
            on_retry(events.RETRY, device=device, what=what, attempt=attempt, error=str(exc))
            clock.sleep(wait)
            wait = min(2 * wait, policy.max_backoff_s)
            if reconnect is not None:
                try:
                    reconnect()
                    on_retry(events.RECONNECT, device=device, what=what, attempt=attempt)
                except DeviceError as again:
                    on_retry(events.RECONNECT_FAILED, device=device, what=what, attempt=attempt, error=str(again))
    raise AssertionError("unreachable")


class RetryingDevice:
    """A driver that runs its exchanges under `retry` on `clock` and reports to `events`.

    Subclasses say how to get back in step after a fault (`reconnect`); the
    sink is looked up at event time, so rerouting `events` takes effect at once.
    """

    def __init__(self, name: str, clock: Clock, retry: RetryPolicy):
        self.name = name
        self.clock = clock
        self.retry = retry
        self.events: EventSink = no_events

    def reconnect(self) -> None:
        """Re-establish the link before a retry; raise a transient DeviceError if that fails."""
        raise NotImplementedError

    def retrying(self, what: str, action: Callable[[], T], *, policy: RetryPolicy | None = None,
                 reconnect: bool = True, device: str | None = None) -> T:
        """Run `action` under `policy` (default: the driver's), reconnecting before each retry.

        `device` names who failed when it is not the driver itself (an axis of a controller).
        """
        return call_with_retry(action, device=device or self.name, what=what, clock=self.clock,
                               policy=policy or self.retry, on_retry=self._report,
                               reconnect=self.reconnect if reconnect else None)

    def _report(self, kind: str, **fields: Any) -> None:
        self.events(kind, **fields)
