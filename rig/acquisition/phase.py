"""The run's phase in its dataset folder (phase.json, docs/dataset.md): what the engine is doing now, written at
each change, so that the monitor reads it instead of working it out from the kinds of the events.

A small file of its own, replaced whole (written beside, then renamed) at each change: the append-only files keep
every line they had, and a folder without it (written by an older version) is followed as before. Advisory: a write
that fails (a full disk) is skipped and the run goes on; how the run ended is the manifest's `status`.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Callable
from pathlib import Path

from rig.core.events import PHASE_FILE
from rig.data.dataset_writer import utc_now


class PhaseFile:
    """phase.json of one run: `set(phase, detail)` replaces it when the phase or its detail changes."""

    def __init__(self, folder: Path, rig_time_s: Callable[[], float]):
        self.path, self.rig_time_s = folder / PHASE_FILE, rig_time_s
        self.now: tuple[str, str] | None = None

    def set(self, phase: str, detail: str = "") -> None:
        """`phase`: one of rig.core.events.PHASES; `detail`: why (a pause's device and reason, a stop's reason)."""
        if self.now == (phase, detail):
            return
        self.now = phase, detail
        record = {"phase": phase, "detail": detail, "rig_time_s": self.rig_time_s(), "time_utc": utc_now()}
        tmp = self.path.with_name(PHASE_FILE + ".tmp")
        try:
            tmp.write_text(json.dumps(record) + "\n", encoding="utf-8")
            os.replace(tmp, self.path)
        except OSError:              # advisory: never the reason a run stops
            with contextlib.suppress(OSError):
                tmp.unlink(missing_ok=True)
