"""Retries with back-off, for transient device errors only.

A transient fault (timeout, garbled reply, dropped link) costs a retry, after
an optional reconnect, and an event; anything else, or a fault that outlasts
the attempts, propagates as a persistent DeviceError.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, TypeVar

from rig.core.clock import Clock
from rig.core.errors import DeviceError

T = TypeVar("T")


@dataclass(frozen=True)
class RetryPolicy:
    attempts: int = 3
    backoff_s: float = 0.05      # first wait; doubles each time
    max_backoff_s: float = 2.0


def call_with_retry(action: Callable[[], T], *, device: str, what: str, clock: Clock, policy: RetryPolicy,
                    on_retry: Callable[..., None], reconnect: Callable[[], None] | None = None) -> T:
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
            on_retry("retry", device=device, what=what, attempt=attempt, error=str(exc))
            clock.sleep(wait)
            wait = min(2 * wait, policy.max_backoff_s)
            if reconnect is not None:
                try:
                    reconnect()
                    on_retry("reconnect", device=device, what=what, attempt=attempt)
                except DeviceError as again:
                    on_retry("reconnect_failed", device=device, what=what, attempt=attempt, error=str(again))
    raise AssertionError("unreachable")
