"""Errors that cross layers."""

from __future__ import annotations


class DeviceError(RuntimeError):
    """A device refused, timed out or answered nonsense.

    The message names the device and what it answered; `transient` tells the
    driver whether a retry may help, `unanswered` that retries did not.
    """

    def __init__(self, device: str, message: str, *, transient: bool = False, unanswered: bool = False):
        super().__init__(f"{device}: {message}")
        self.device = device
        self.transient = transient
        #: Transient faults outlasted the retries: the device stopped answering. The run
        #: engine pauses for it (a suspender) rather than failing at once.
        self.unanswered = unanswered
