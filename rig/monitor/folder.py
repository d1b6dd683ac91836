"""Following a dataset folder while `rig run` writes it (docs/dataset.md), without changing or locking it.

brdf.csv and events.jsonl are append-only and every line is on disk before the next one: the
follower keeps an offset per file and parses only the bytes appended since its last look, up
to the last newline; a last line without its newline (a write in progress, or a kill) is left
for the next look, as every reader of the folder does. dataset.json and skipped.csv are replaced
atomically (rename), so they are read whole when their size or modification time changes. A
folder or file that is not the one read so far (another device or inode, a file shorter than read or
with other first bytes, a manifest of another run: the folder was removed and made again, or replaced
by a copy that reuses the inode numbers) makes it start over, with a new `generation`; two runs are
never mixed. Whatever the files hold, a line that cannot be followed is skipped and reported, and a
file that cannot be read (rig.monitor.files: a FIFO in its place, too large) is a warning, never a hang.

What the page needs grows without bound on an overnight run (points, E⊥ readings, events), so
it goes into an append-only list of changes that a viewer asks for from where it stopped
(`snapshot(since)`); the rest (progress, state, ETA, budget, skipped points) is small and sent
whole. Opening the files read-only takes no lock: the writer's `flock` on `.lock`
(rig/data/folderlock.py) is advisory and concerns writers only.
"""

from __future__ import annotations

import csv
import os
import stat
import uuid
from collections import Counter, deque
from collections.abc import Callable
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from rig.core import events
from rig.monitor import files
from rig.monitor.phase import PHASE_OF_STATUS, WrittenPhase, detail_of, phase_after
from rig.monitor.records import (
    PlanSummary,
    RunAxis,
    WarmupState,
    finite_float,
    plan_of,
    point_record,
    section,
    short_text,
    summarize_event,
    text_of,
    utc_seconds,
)
from rig.physics.budget import BUDGET_COLUMNS, campaign_budget, mark_not_stated, not_stated
from rig.planning.points import SKIP_REASONS, describe_reason

#: Events not shown in the list of recent events: one per point, the points are plotted instead.
QUIET_EVENTS = frozenset({events.POINT_PENDING})
#: Messages about skipped lines kept for the page (the count of all is `bad_lines`).
WARNINGS_KEPT = 10
#: Most points a manifest's counts may name (a paper campaign plans a few thousand).
MAX_POINTS = 10 ** 9


class BadLine(Exception):
    """A line of brdf.csv or events.jsonl that cannot be followed: skipped and reported, with this reason."""


class FolderFollower:
    """The state of one dataset folder, brought up to date by `update()` and read by `snapshot()`.

    Not thread-safe: one caller at a time (the server holds a lock around both).
    """

    def __init__(self, folder: str | Path):
        self.folder = Path(folder)
        self._reset()

    def _reset(self) -> None:
        self.generation = uuid.uuid4().hex[:12]
        self.rows, self.events = files.Tail(self.folder / "brdf.csv"), files.Tail(self.folder / "events.jsonl")
        self._identity: tuple[int, int] | None = None        # the folder's (device, inode)
        self._run: str | None = None                          # the manifest's `created_utc`: which run
        self.header: list[str] | None = None
        self.changes: list[dict[str, Any]] = []
        self.manifest: dict[str, Any] = {}
        self.manifest_error: str | None = None
        self._manifest_stamp: tuple[int, int, int] | None = None
        self._skipped_stamp: tuple[int, int, int] | None = None
        self.written_phase = WrittenPhase(self.folder)
        self.skipped: Counter[str] = Counter()
        self.plan: PlanSummary | None = None
        self.batch_points = 0                        # points of `adaptive_batch` events (docs/sampling.md)
        self.final: set[str] = set()                 # point ids in brdf.csv
        self.pending: set[str] = set()               # written ahead, not (yet) in brdf.csv
        self.budget_rows: dict[str, dict[str, float]] = {}
        self._budget: list[dict] | None = None
        self.flags: Counter[str] = Counter()
        self.axis, self.warmup = RunAxis(), WarmupState()      # the campaign's rig-time axis; the lamp's warm-up
        self.phase, self.detail = "starting", ""
        self.aligned = False
        self.rig_time_s: float | None = None
        self.last_utc: str | None = None
        self.active_s = 0.0                            # rig time in `measuring`, for the ETA
        self.active_since: float | None = None
        self.session_done: int | None = None           # points done when this session began measuring
        self.rate_origin: tuple[float, float] | None = None   # (wall s, rig s) then
        self.rate_latest: tuple[float, float] | None = None
        self.bad_lines = 0
        self.warnings: deque[str] = deque(maxlen=WARNINGS_KEPT)
        self.problems: dict[str, str] = {}            # file name → why it cannot be read now

    # -- reading ---------------------------------------------------------------------------------
    def update(self) -> None:
        """Read what was written since the last call."""
        try:
            self._update()
        except files.Replaced:
            self._reset()
            self._update()

    def _update(self) -> None:
        try:
            st = os.stat(self.folder)
        except OSError:
            return
        if not stat.S_ISDIR(st.st_mode):
            return
        if self._identity not in (None, (st.st_dev, st.st_ino)):
            raise files.Replaced(self.folder)
        self._identity = st.st_dev, st.st_ino
        self._read_manifest()
        self.written_phase.read(self.problems)
        self._read_skipped()
        self._follow(self.events, self._event_line)
        self._follow(self.rows, self._row_line)

    def _follow(self, tail: files.Tail, follow: Callable[[str], None]) -> None:
        """The new lines of one file, each followed or skipped with a warning naming the file and line."""
        try:
            lines = tail.new_lines()
        except files.FollowError as exc:
            self.problems[tail.path.name] = str(exc)
            return
        self.problems.pop(tail.path.name, None)
        for number, data in lines:
            try:
                if data is None:
                    raise BadLine(f"longer than {files.MAX_LINE_BYTES} bytes")
                follow(data.decode("utf-8", "replace").removesuffix("\r"))
            except BadLine as exc:
                self.bad_lines += 1
                self.warnings.append(f"{tail.path.name} line {number}: {exc}; skipped")

    @staticmethod
    def _stamp(path: Path) -> tuple[int, int, int] | None:
        try:
            st = path.stat()
        except OSError:
            return None
        return st.st_ino, st.st_size, st.st_mtime_ns

    def _read_manifest(self) -> None:
        """dataset.json when it changed; one of another run (its `created_utc`) means the folder was replaced."""
        stamp = self._stamp(self.folder / "dataset.json")
        if stamp is None or stamp == self._manifest_stamp:
            return
        self._manifest_stamp = stamp
        try:
            data = files.read_whole(self.folder / "dataset.json", files.WHOLE_FILE_BYTES)
            if data is None:
                return
            manifest = files.parse_manifest(data)
        except files.FollowError as exc:
            self.manifest_error = f"{self.folder / 'dataset.json'}: {str(exc).partition(': ')[2]}; cannot follow it"
            return
        run = text_of(manifest.get("created_utc"))
        if self._run is not None and run != self._run:
            raise files.Replaced(self.folder / "dataset.json")
        self.manifest, self.manifest_error, self._run = manifest, None, run
        if self.plan is None and "campaign" in self.manifest:
            self.plan = plan_of(self.manifest)

    def _read_skipped(self) -> None:
        path = self.folder / "skipped.csv"
        stamp = self._stamp(path)
        if stamp is None or stamp == self._skipped_stamp:
            return
        self._skipped_stamp = stamp
        try:
            data = files.read_whole(path, files.WHOLE_FILE_BYTES) or b""
            text = data[:data.rfind(b"\n") + 1].decode("utf-8", "replace")
            self.skipped = Counter(short_text(r.get("reason") or "?", 80) for r in csv.DictReader(text.split("\n")))
        except csv.Error as exc:
            self.problems[path.name] = f"{path.name}: not CSV ({exc}); skipped points not counted"
        except files.FollowError as exc:
            self.problems[path.name] = str(exc)
        else:
            self.problems.pop(path.name, None)

    def _row_line(self, line: str) -> None:
        try:
            values = next(csv.reader([line]), [])
        except csv.Error as exc:
            raise BadLine(f"not a CSV row ({exc})") from None
        if self.header is None:
            self.header = values
            return
        if len(values) != len(self.header):
            raise BadLine(f"{len(values)} fields, the header has {len(self.header)}")
        self._keep(dict(zip(self.header, values)), final=True)

    def _keep(self, row: dict[str, Any], *, final: bool) -> None:
        """A measured point: plotted, counted, and its budget and flags noted."""
        record = point_record(row)
        pid = record["id"]
        (self.final if final else self.pending).add(pid)
        if final:
            self.pending.discard(pid)
            flags = row.get("flags", "")
            self.flags.update(f for f in (flags.split(";") if isinstance(flags, str) else flags) if f)
        budget = {c: finite_float(row.get(c)) for c in BUDGET_COLUMNS}
        if all(v is not None for v in budget.values()):
            self.budget_rows[pid] = budget  # type: ignore[assignment]
            self._budget = None
        self.changes.append(record)
        self._at(row.get("time_utc"), finite_float(row.get("rig_time_s")))

    def _event_line(self, line: str) -> None:
        """One event: checked whole before anything of it is kept, so that a bad line changes nothing."""
        try:
            event = files.strict_json(line)
        except ValueError as exc:
            raise BadLine(f"not valid JSON ({short_text(str(exc).splitlines()[0], 120)})") from None
        if not isinstance(event, dict):
            raise BadLine(f"a JSON {type(event).__name__}, not an event object")
        kind = short_text(event["event"], 60) if isinstance(event.get("event"), str) else "?"
        row, ids = event.get("row"), event.get("point_ids")
        if kind == events.POINT_PENDING and isinstance(row, dict) and not isinstance(row.get("point_id"), str):
            raise BadLine("point_pending: its row's point_id is not text")
        if kind == events.POINTS_DISCARDED and isinstance(ids, list) and not all(isinstance(p, str) for p in ids):
            raise BadLine("points_discarded: a point id that is not text")
        rig_s = self.axis.place(kind, finite_float(event.get("rig_time_s")), self.manifest)
        summary = summarize_event(event) if kind not in QUIET_EVENTS else ""
        if kind == events.POINT_PENDING and isinstance(row, dict):
            if row["point_id"] not in self.final:
                self._keep(row, final=False)
        elif kind == events.POINTS_DISCARDED and isinstance(ids, list):
            for pid in ids:
                if pid in self.pending:
                    self.pending.discard(pid)
                    self.budget_rows.pop(pid, None)
                    self._budget = None
                    self.changes.append({"k": "d", "id": pid})
        elif kind == events.ILLUMINANCE:
            self.changes.append({"k": "e", "t": rig_s, "lx": finite_float(event.get("illuminance_normal_lx")),
                                 "u": finite_float(event.get("u_lx")), "r": self.axis.run})
        elif kind == events.ADAPTIVE_BATCH and isinstance(event.get("points"), list):
            self.batch_points += len(event["points"])      # an adaptive campaign's plan grows batch by batch
        elif kind in (events.LAMP_ON, events.WARMUP_STABLE, events.WARMUP_NOT_STABLE):
            self.changes.append({"k": "l", "t": rig_s, "i": finite_float(event.get("current_a")), "r": self.axis.run,
                                 "v": finite_float(event.get("voltage_v", event.get("lamp_voltage_v")))})
        self.warmup.note(kind, event, rig_s, self.changes, self.axis.run)
        self._at(event.get("time_utc"), rig_s)
        self._phase(kind, event, rig_s)
        if kind not in QUIET_EVENTS:
            utc = event.get("time_utc")
            self.changes.append({"k": "ev", "utc": utc if utc_seconds(utc) is not None else None, "t": rig_s,
                                 "event": kind, "text": summary})

    def _at(self, time_utc: Any, rig_s: float | None) -> None:
        """The run's latest time, wall and rig."""
        wall = utc_seconds(time_utc)
        if wall is not None:
            self.last_utc = time_utc
        if rig_s is not None:
            self.rig_time_s = rig_s if self.rig_time_s is None else max(self.rig_time_s, rig_s)
            if wall is not None and self.phase == "measuring":
                self.rate_latest = (wall, rig_s)
                if self.rate_origin is None:
                    self.rate_origin = (wall, rig_s)

    def _phase(self, kind: str, event: dict[str, Any], rig_s: float | None) -> None:
        """What an event says of the run: a new session (a resume), the stretches of measuring the ETA counts, and
        the phase shown for a folder without phase.json (written by an older version)."""
        if kind == events.RESUME:                     # a new session: its own rate
            self.session_done, self.rate_origin, self.rate_latest = None, None, None
            self.active_s, self.active_since = 0.0, None
        self.aligned = self.aligned or kind == events.ALIGNED
        phase = phase_after(kind, self.phase, self._aligning)
        if phase is None:
            return
        was_measuring = self.phase == events.MEASURING
        self.phase, self.detail = phase, detail_of(phase, kind, event)
        if rig_s is not None:
            self._measuring_stretch(was_measuring, rig_s)

    def _measuring_stretch(self, was_measuring: bool, rig_s: float) -> None:
        """Rig time measuring (warm-up and pauses left out), for the ETA."""
        if was_measuring and self.phase != events.MEASURING and self.active_since is not None:
            self.active_s += rig_s - self.active_since
            self.active_since = None
        elif self.phase == events.MEASURING and not was_measuring:
            self.active_since = rig_s
            if self.session_done is None:
                self.session_done = self.done

    def _aligning(self) -> bool:
        content = section(self.manifest, "campaign").get("content")
        return isinstance(content, dict) and content.get("alignment") is not None and not self.aligned

    # -- what the page shows -----------------------------------------------------------------
    @property
    def done(self) -> int:
        return len(self.final | self.pending)

    def state(self) -> tuple[str, str]:
        """(phase, detail): the run's phase.json (the events' phase in a folder without one), overruled by the
        manifest once the run has ended, and by a writer that is gone while the manifest still says `running`
        (killed)."""
        if not self.folder.is_dir():
            return "waiting", "the folder does not exist yet (the run creates it)"
        if self.manifest_error:
            return "unreadable", self.manifest_error
        if not self.manifest:
            return "waiting", "no dataset.json yet"
        status = self.manifest.get("status")
        if status in PHASE_OF_STATUS:
            detail = self.manifest.get("error") if status == "failed" else self.detail
            return PHASE_OF_STATUS[status], short_text(str(detail or ""))
        if status == "running" and files.writer_alive(self.folder) is False:
            return "abandoned", ("the writing process is gone without closing the folder (killed?); "
                                 "`rig run --resume` continues it")
        return self.written_phase.now or (self.phase, self.detail)

    def _to_measure(self) -> int | None:
        counts = section(self.manifest, "counts")
        planned, skipped = counts.get("planned"), counts.get("skipped")
        if isinstance(planned, int) and isinstance(skipped, int) and 0 <= skipped <= planned <= MAX_POINTS:
            return planned - skipped
        return self.plan.to_measure + self.batch_points if self.plan and self.plan.to_measure is not None else None

    def _eta(self, phase: str, to_measure: int | None) -> dict[str, float | None]:
        """Rig time left: the points left × the rig time measuring per point so far in this session (warm-up
        and pauses excluded, like rig.acquisition.eta); wall time: × the wall seconds per rig second seen."""
        eta: dict[str, float | None] = {"rig_s": None, "wall_s": None, "wall_per_rig": None}
        if phase in PHASE_OF_STATUS.values() or phase == "abandoned" or to_measure is None:
            return eta
        active = self.active_s
        if self.active_since is not None and self.rig_time_s is not None:
            active += self.rig_time_s - self.active_since
        n = self.done - (self.session_done or 0)
        if phase in ("starting", "warm-up") and self.plan and self.plan.estimate_s is not None:    # before a point
            eta["rig_s"] = (self.warmup.state(self.manifest, self.rig_time_s)["left_s"] or 0.0) + self.plan.estimate_s
        if n <= 0 or active <= 0:
            return eta
        eta["rig_s"] = left_s = max(to_measure - self.done, 0) * active / n
        if self.rate_origin and self.rate_latest and self.rate_latest[1] > self.rate_origin[1]:
            per = (self.rate_latest[0] - self.rate_origin[0]) / (self.rate_latest[1] - self.rate_origin[1])
            eta["wall_per_rig"], eta["wall_s"] = per, left_s * per
        return {k: finite_float(v) for k, v in eta.items()}       # absurd times written: no ETA, never inf

    def budget(self) -> list[dict]:
        """The uncertainty budget of the points so far (rig.physics.budget, as the manifest has it at the end),
        naming the calibrations whose u the rig file did not state."""
        if self._budget is None:
            table = campaign_budget(list(self.budget_rows.values()), BUDGET_COLUMNS)
            self._budget = [{k: finite_float(v) if isinstance(v, float) else v for k, v in component.items()}
                            for component in mark_not_stated(table, not_stated(self.manifest))]
        return self._budget

    def snapshot(self, since: int = 0) -> dict[str, Any]:
        """Everything the page shows, with the changes from `since` on (0 after a new `generation`)."""
        phase, detail = self.state()
        to_measure = self._to_measure()
        m = self.manifest
        sample, rig = section(m, "sample"), section(m, "rig")
        return {
            "folder": str(self.folder), "generation": self.generation, "next": len(self.changes),
            "changes": self.changes[max(since, 0):],
            "now_utc": datetime.now(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z"),
            "last_utc": self.last_utc, "created_utc": text_of(m.get("created_utc")),
            "finished_utc": text_of(m.get("finished_utc")), "campaign": text_of(section(m, "campaign").get("name")),
            "sample": text_of(sample.get("id")), "sample_description": text_of(sample.get("description")),
            "rig": text_of(rig.get("name")), "simulated": rig.get("simulated") if rig.get("simulated") in (True, False)
            else None, "software": text_of(section(m, "software").get("version")),
            "status": text_of(m.get("status")), "phase": phase, "detail": detail,
            "progress": {"done": self.done, "to_measure": to_measure, "in_csv": len(self.final),
                         "pending": len(self.pending - self.final), "skipped": sum(self.skipped.values())},
            "rig_time_s": self.rig_time_s, "eta": self._eta(phase, to_measure),
            "warmup": self.warmup.state(self.manifest, self.rig_time_s) if phase == "warm-up" else None,
            "series": self.plan.series if self.plan else [], "plan_error": self.plan.error if self.plan else None,
            "skipped": [{"reason": r, "count": n, "meaning": describe_reason(r) if r.partition(":")[0] in SKIP_REASONS
                         else ""} for r, n in self.skipped.most_common()],
            "flags": dict(self.flags.most_common()), "budget": self.budget(), "bad_lines": self.bad_lines,
            "warnings": [*self.problems.values(), *self.warnings],
        }

