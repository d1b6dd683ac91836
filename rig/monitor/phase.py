"""The run's phase as the monitor shows it: the phase.json the engine writes at each change (rig.acquisition.phase),
or, in a folder without one (written by an older version), the phase worked out from the kinds of its events."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from rig.core import events
from rig.monitor import files
from rig.monitor.records import short_text

#: The run's phase after an event of these kinds (docs/dataset.md, events.jsonl); other kinds leave it.
PHASE_AFTER = {events.DEVICES: events.STARTING, events.RESUME: events.STARTING, events.LAMP_ON: events.WARMING_UP,
               events.WARMUP_STABLE: events.MEASURING, events.WARMUP_NOT_STABLE: events.MEASURING,
               events.ALIGNMENT_SCAN: events.ALIGNING, events.ALIGNED: events.MEASURING,
               events.SUSPENDED: events.PAUSED, events.RESUMED: events.MEASURING,
               events.STOP_REQUESTED: events.STOPPING,
               events.INTERRUPTED: "interrupted", events.FAILED: "failed", events.SAFE_STATE: events.CLOSING}
#: The phase of a folder whose manifest says the run ended, whatever the last event was.
PHASE_OF_STATUS = {"complete": "finished", "interrupted": "interrupted", "failed": "failed"}


class WrittenPhase:
    """A folder's phase.json, read again when it changed (its inode, size or modification time)."""

    def __init__(self, folder: Path):
        self.path = folder / events.PHASE_FILE
        self.stamp: tuple[int, int, int] | None = None
        #: (phase, detail), or None: no phase.json (an older version's folder), or one that cannot be read.
        self.now: tuple[str, str] | None = None

    def read(self, problems: dict[str, str]) -> None:
        """Bring `now` up to date; what is wrong with the file goes into `problems` (by file name), never raised."""
        try:
            st = self.path.stat()
            stamp: tuple[int, int, int] | None = st.st_ino, st.st_size, st.st_mtime_ns
        except OSError:
            stamp = None
        if stamp == self.stamp:
            return
        self.stamp, self.now = stamp, None
        problems.pop(self.path.name, None)
        try:
            data = files.read_whole(self.path, files.WHOLE_FILE_BYTES) if stamp is not None else None
            record = files.strict_json(data) if data is not None else None
        except (files.FollowError, ValueError) as exc:
            problems[self.path.name] = f"{self.path.name}: {short_text(str(exc).splitlines()[0], 100)}; phase of events"
            return
        if isinstance(record, dict) and record.get("phase") in events.PHASES and isinstance(record.get("detail"), str):
            self.now = record["phase"], short_text(record["detail"])
        elif record is not None:
            problems[self.path.name] = f"{self.path.name}: not a phase record; phase of the events"


def phase_after(kind: str, phase: str, aligning: Callable[[], bool]) -> str | None:
    """The phase after an event of `kind` in `phase` (a folder without phase.json); None: it leaves it as it was.
    `aligning()`: the campaign aligns the arm and has not yet (a warm-up's end then begins the alignment)."""
    after = PHASE_AFTER.get(kind)
    if after == events.CLOSING and phase in ("interrupted", "failed"):
        return None
    if after == events.MEASURING and kind.startswith("warmup") and aligning():
        return events.ALIGNING
    return after


def detail_of(phase: str, kind: str, event: dict[str, Any]) -> str:
    """What the page says beside a phase worked out from an event (a folder without phase.json)."""
    return {events.PAUSED: short_text(f"{event.get('device', '?')}: {event.get('reason', '')}"),
            events.STOPPING: short_text(str(event.get("reason", ""))),
            "interrupted": short_text(str(event.get("reason", ""))),
            "failed": short_text(str(event.get("error", ""))),
            events.WARMING_UP: "lamp switched on" if kind == events.LAMP_ON else ""}.get(phase, "")
