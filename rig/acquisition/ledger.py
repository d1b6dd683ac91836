"""The measured points of a run: rows written, points waiting for their closing E⊥ reading, the count, and the
checkpoints a tripped suspender rewinds to.

The one place the count of measured points changes: up when a point is kept, down when a rewind discards points
(they are measured again; `points_discarded`). With `illuminance.correction: interpolate` a point waits, written
ahead, for the E⊥ reading after it; until then it can be taken back.

Checkpoints (Bluesky's idea: a suspender rewinds to a checkpoint the plan names). Two marks: `Mark.READING`, where
E⊥ was last read (every waiting point lies after it), and `Mark.LAMP_CHECKED`, where a lamp check last passed. The
lamp is checked on a schedule (rig.acquisition.suspenders), so a check vouches only for the points measured before
it. A tripped suspender's verdict names its mark; `rewind` discards the waiting points since it, and always those
since the lamp check as well: every other way a row becomes final (a pause writes the waiting rows, and so does the
exit) comes without a check, and an unvouched row must not become final (`--resume` measures it again). The lamp
mark counts the points started since the check, kept or not (`started`): a point whose device went silent still
counts, so at worst one point is measured once more (as when the lamp was checked before every point).
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Sequence

from rig.acquisition.eta import Eta
from rig.acquisition.rows import Measurement, RowConstants, bracketed_rows, latest_row
from rig.core import events
from rig.data.dataset_writer import DatasetWriter
from rig.physics.illuminance import IlluminanceEstimate
from rig.planning.points import PlannedPoint


class Mark(enum.Enum):
    """A checkpoint a tripped suspender rewinds to (module docstring)."""

    READING = "E⊥ read"                  # the last E⊥ reading: every waiting point is after it
    LAMP_CHECKED = "lamp checked"        # the last passing lamp check


class Ledger:
    """Rows go to `writer`; with `interpolate`, a point waits (written ahead) for the next E⊥ reading."""

    def __init__(self, writer: DatasetWriter, done_rows: Sequence[dict], constants: RowConstants,
                 interpolate: bool, eta: Eta, rig_time_s: Callable[[], float]):
        """`done_rows`: rows already in the dataset (a resume)."""
        self.writer = writer
        self.constants = constants
        self.interpolate = interpolate
        self.eta = eta
        self.rig_time_s = rig_time_s
        self.rows: list[dict] = list(done_rows)      # written rows, for the campaign budget
        self.pending: list[Measurement] = []        # waiting for the next E⊥ reading
        self.measured = len(done_rows)
        self._started_since_check = 0               # points started since the last passing lamp check

    def keep(self, m: Measurement, reading: IlluminanceEstimate) -> None:
        """Count a measured point and append its row, or write it ahead until E⊥ brackets it."""
        self.measured += 1
        self.eta.done(m.point.point_id)
        row = latest_row(m, reading, self.constants)
        if self.interpolate:
            self.pending.append(m)
            # a crash before the next reading loses nothing; fsync'ed behind, off the point's path
            self.writer.event_synced_behind(events.POINT_PENDING, row=row)
        else:
            self._append([row])

    def started(self) -> None:
        """A point goes ahead (no polled suspender tripped): it lies after every mark, whether it is kept or not."""
        self._started_since_check += 1

    def mark(self, mark: Mark) -> None:
        """A checkpoint at the current point: a lamp check passed (an E⊥ reading marks itself: `write_pending`)."""
        if mark is Mark.LAMP_CHECKED:
            self._started_since_check = 0

    def since(self, mark: Mark) -> int:
        """How many of the waiting points lie after `mark`."""
        waiting = len(self.pending)
        return waiting if mark is Mark.READING else min(self._started_since_check, waiting)

    def rewind(self, to: Mark | None, reason: str) -> list[PlannedPoint]:
        """Discard the waiting points since `to` (None: no mark of its own), and those since the lamp check
        (module docstring); a `points_discarded` event with `reason`. The discarded points, to measure again."""
        n = max(self.since(to) if to is not None else 0, self.since(Mark.LAMP_CHECKED))
        self._started_since_check = max(self._started_since_check - n, 0)
        points = [m.point for m in self.pending[len(self.pending) - n:]]
        del self.pending[len(self.pending) - n:]
        if points:
            self.measured -= len(points)
            self.eta.undone(p.point_id for p in points)
            self.writer.event(events.POINTS_DISCARDED, point_ids=[p.point_id for p in points], reason=reason,
                              rig_time_s=self.rig_time_s())
        return points

    def write_pending(self, before: IlluminanceEstimate | None, after: IlluminanceEstimate | None) -> None:
        """Append the waiting points with E⊥ interpolated between `before` and `after` (or `before` alone).

        Points only wait after a reading, so `before` is None only when none waits. The rows go out in one
        write and one fsync (`DatasetWriter.append_rows`): each is on disk before this returns.
        """
        if before is not None:
            self._append(bracketed_rows(self.pending, before, after, self.constants))
        self.pending.clear()

    def _append(self, rows: Sequence[dict]) -> None:
        self.writer.append_rows(rows)
        self.rows.extend(rows)
