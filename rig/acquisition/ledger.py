"""The measured points of a run: rows written, points waiting for their closing E⊥ reading, the count.

The one place the count of measured points changes: up when a point is kept, down when
a tripped suspender discards points (they are measured again).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from rig.acquisition.eta import Eta
from rig.acquisition.rows import Measurement, RowConstants, bracketed_rows, latest_row
from rig.data.dataset_writer import DatasetWriter
from rig.physics.illuminance import IlluminanceEstimate
from rig.planning.points import PlannedPoint


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

    def keep(self, m: Measurement, reading: IlluminanceEstimate) -> None:
        """Count a measured point and append its row, or write it ahead until E⊥ brackets it."""
        self.measured += 1
        self.eta.done(m.point.point_id)
        row = latest_row(m, reading, self.constants)
        if self.interpolate:
            self.pending.append(m)
            # a crash before the next reading loses nothing; fsync'ed behind, off the point's path
            self.writer.event_synced_behind("point_pending", row=row)
        else:
            self._append([row])

    def discard_last(self, n: int, reason: str) -> list[PlannedPoint]:
        """Discard the last `n` points waiting for E⊥ (they are measured again); returns their points."""
        points = [m.point for m in self.pending[len(self.pending) - n:]]
        del self.pending[len(self.pending) - n:]
        if points:
            self.measured -= len(points)
            self.eta.undone(p.point_id for p in points)
            self.writer.event("points_discarded", point_ids=[p.point_id for p in points], reason=reason,
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
