"""How a run ended: the one place that turns what ended it into a status.

The engine, `execute` and the soak runs all end a run the same way, so they ask
`ending_of` instead of each deciding: nothing raised → `complete`; a graceful stop →
`interrupted` (graceful); an abort or Ctrl+C → `interrupted`; any other error → `failed`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

from rig.acquisition.stopping import AbortRequested, StopRequested
from rig.core import events
from rig.data.dataset_writer import DatasetWriter

Status = Literal["complete", "interrupted", "failed"]


@dataclass(frozen=True)
class RunEnding:
    """A run's status, whether it stopped gracefully, and the error that failed it."""

    status: Status
    graceful: bool = False
    #: The manifest's and the `failed` event's `error`: the exception's type and message.
    error: str | None = None
    #: What the operator is told (`rig run`, the soak's attempts): the exception's message.
    message: str | None = None


#: A run that measured every point it had to.
COMPLETE = RunEnding("complete")
#: A run ended by something that is not an Exception (e.g. SystemExit) before it could say more.
UNKNOWN_FAILURE = RunEnding("failed")


def ending_of(exc: BaseException | None) -> RunEnding:
    """How a run ended, from what ended it (None: it ran to its end)."""
    if exc is None:
        return COMPLETE
    if isinstance(exc, StopRequested):
        return RunEnding("interrupted", graceful=True)
    if isinstance(exc, (AbortRequested, KeyboardInterrupt)):
        return RunEnding("interrupted")
    if isinstance(exc, Exception):
        return RunEnding("failed", error=f"{type(exc).__name__}: {exc}", message=str(exc))
    return UNKNOWN_FAILURE


def record_unstarted(writer: DatasetWriter, ending: RunEnding) -> None:
    """Event and manifest status of a run that ended before its engine existed (the rig never came up).

    Nothing was switched on, so there is no rig time, no count and no safe state to record.
    """
    if ending.status == "interrupted":
        writer.event(events.INTERRUPTED, graceful=ending.graceful)
        writer.update_manifest(status=ending.status)
    else:
        writer.event(ending.status, error=ending.message)
        writer.update_manifest(status=ending.status, error=ending.message)
