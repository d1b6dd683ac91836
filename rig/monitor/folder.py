"""Following a dataset folder while `rig run` writes it (docs/dataset.md), without changing or locking it.

brdf.csv and events.jsonl are append-only and every line is on disk before the next one: the
follower keeps an offset per file and parses only the bytes appended since its last look, up
to the last newline; a last line without its newline (a write in progress, or a kill) is left
for the next look, as every reader of the folder does. dataset.json and skipped.csv are replaced
atomically (rename), so they are read whole when their size or modification time changes. A
file that shrank or changed inode under the follower (the folder was removed and made again)
makes it start over, with a new `generation`.

What the page needs grows without bound on an overnight run (points, E⊥ readings, events), so
it goes into an append-only list of changes that a viewer asks for from where it stopped
(`snapshot(since)`); the rest (progress, state, ETA, budget, skipped points) is small and sent
whole. Opening the files read-only takes no lock: the writer's `flock` on `.lock`
(rig/data/folderlock.py) is advisory and concerns writers only.
"""

from __future__ import annotations

import csv
import json
import os
import socket
import uuid
from collections import Counter
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from rig.data.dataset_format import DatasetError
from rig.data.dataset_reader import read_manifest
from rig.data.folderlock import LOCK_NAME
from rig.monitor.records import PlanSummary, finite_float, plan_of, point_record, summarize_event
from rig.physics.budget import BUDGET_COLUMNS, campaign_budget
from rig.planning.points import SKIP_REASONS, describe_reason

#: The run's phase after an event of these kinds (docs/dataset.md, events.jsonl); other kinds leave it.
PHASE_AFTER = {"devices": "starting", "resume": "starting", "lamp_on": "warm-up", "warmup_stable": "measuring",
               "warmup_not_stable": "measuring", "alignment_scan": "aligning", "aligned": "measuring",
               "suspended": "paused", "resumed": "measuring", "stop_requested": "stopping",
               "interrupted": "interrupted", "failed": "failed", "safe_state": "closing"}
#: The phase of a folder whose manifest says the run ended, whatever the last event was.
PHASE_OF_STATUS = {"complete": "finished", "interrupted": "interrupted", "failed": "failed"}
#: Events not shown in the list of recent events: one per point, the points are plotted instead.
QUIET_EVENTS = frozenset({"point_pending"})


@dataclass
class _Tail:
    """An append-only file read from where the previous read stopped, complete lines only."""

    path: Path
    offset: int = 0
    inode: int | None = None

    def new_lines(self) -> list[str]:
        """Lines completed since the last call ([] while the file is absent); _Replaced if it shrank or is
        another file now."""
        try:
            with open(self.path, "rb") as fh:
                st = os.fstat(fh.fileno())
                if (self.inode is not None and st.st_ino != self.inode) or st.st_size < self.offset:
                    raise _Replaced(self.path)
                self.inode = st.st_ino
                fh.seek(self.offset)
                data = fh.read()
        except FileNotFoundError:
            if self.inode is not None:
                raise _Replaced(self.path) from None
            return []
        keep = data.rfind(b"\n") + 1
        self.offset += keep
        return data[:keep].decode("utf-8", "replace").splitlines()


class _Replaced(Exception):
    """A followed file is not the one read so far: start over."""


def _utc_s(text: Any) -> float | None:
    """An ISO 8601 UTC time as POSIX seconds; None if it is not one."""
    try:
        return datetime.fromisoformat(str(text)).timestamp()
    except ValueError:
        return None


def _section(manifest: dict[str, Any], key: str) -> dict[str, Any]:
    """A section of the manifest; {} where it is absent or not an object."""
    value = manifest.get(key)
    return value if isinstance(value, dict) else {}


def writer_alive(folder: Path) -> bool | None:
    """Whether the process named in `.lock` (rig/data/folderlock.py: "pid N host H" while a writer holds it,
    left there by a writer that was killed) is running; None when it cannot be told (no name in the file,
    another host)."""
    try:
        text = (folder / LOCK_NAME).read_text(encoding="utf-8", errors="replace").split()
    except OSError:
        return None
    if len(text) < 4 or text[0] != "pid" or text[2] != "host" or not text[1].isdigit():
        return None
    if text[3] != socket.gethostname():
        return None
    try:
        os.kill(int(text[1]), 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True          # someone else's process: it exists
    return True


class FolderFollower:
    """The state of one dataset folder, brought up to date by `update()` and read by `snapshot()`.

    Not thread-safe: one caller at a time (the server holds a lock around both).
    """

    def __init__(self, folder: str | Path):
        self.folder = Path(folder)
        self._reset()

    def _reset(self) -> None:
        self.generation = uuid.uuid4().hex[:12]
        self.rows, self.events = _Tail(self.folder / "brdf.csv"), _Tail(self.folder / "events.jsonl")
        self.header: list[str] | None = None
        self.changes: list[dict[str, Any]] = []
        self.manifest: dict[str, Any] = {}
        self.manifest_error: str | None = None
        self._manifest_stamp: tuple[int, int, int] | None = None
        self._skipped_stamp: tuple[int, int, int] | None = None
        self.skipped: Counter[str] = Counter()
        self.plan: PlanSummary | None = None
        self.batch_points = 0                        # points of `adaptive_batch` events (docs/sampling.md)
        self.final: set[str] = set()                 # point ids in brdf.csv
        self.pending: set[str] = set()               # written ahead, not (yet) in brdf.csv
        self.budget_rows: dict[str, dict[str, float]] = {}
        self._budget: list[dict] | None = None
        self.flags: Counter[str] = Counter()
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

    # -- reading ---------------------------------------------------------------------------------
    def update(self) -> None:
        """Read what was written since the last call."""
        try:
            self._update()
        except _Replaced:
            self._reset()
            self._update()

    def _update(self) -> None:
        if not self.folder.is_dir():
            return
        self._read_manifest()
        self._read_skipped()
        for line in self.events.new_lines():
            self._event_line(line)
        for line in self.rows.new_lines():
            self._row_line(line)

    @staticmethod
    def _stamp(path: Path) -> tuple[int, int, int] | None:
        try:
            st = path.stat()
        except OSError:
            return None
        return st.st_ino, st.st_size, st.st_mtime_ns

    def _read_manifest(self) -> None:
        stamp = self._stamp(self.folder / "dataset.json")
        if stamp is None or stamp == self._manifest_stamp:
            return
        self._manifest_stamp = stamp
        try:
            self.manifest, self.manifest_error = read_manifest(self.folder, purpose="cannot follow it"), None
        except DatasetError as exc:
            self.manifest_error = str(exc)
            return
        if self.plan is None and "campaign" in self.manifest:
            self.plan = plan_of(self.manifest)

    def _read_skipped(self) -> None:
        path = self.folder / "skipped.csv"
        stamp = self._stamp(path)
        if stamp is None or stamp == self._skipped_stamp:
            return
        self._skipped_stamp = stamp
        data = path.read_bytes()
        text = data[:data.rfind(b"\n") + 1].decode("utf-8", "replace")
        self.skipped = Counter(r.get("reason") or "?" for r in csv.DictReader(text.splitlines()))

    def _row_line(self, line: str) -> None:
        values = next(csv.reader([line]), [])
        if self.header is None:
            self.header = values
            return
        if len(values) != len(self.header):
            self.bad_lines += 1
            return
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
        try:
            event = json.loads(line)
        except (json.JSONDecodeError, RecursionError):
            event = None
        if not isinstance(event, dict):
            self.bad_lines += 1
            return
        kind = str(event.get("event", "?"))
        rig_s = finite_float(event.get("rig_time_s"))
        if kind == "point_pending" and isinstance(event.get("row"), dict):
            if event["row"].get("point_id") not in self.final:
                self._keep(event["row"], final=False)
        elif kind == "points_discarded" and isinstance(event.get("point_ids"), list):
            for pid in event["point_ids"]:
                if pid in self.pending:
                    self.pending.discard(pid)
                    self.budget_rows.pop(pid, None)
                    self._budget = None
                    self.changes.append({"k": "d", "id": pid})
        elif kind == "illuminance":
            self.changes.append({"k": "e", "t": rig_s, "lx": finite_float(event.get("illuminance_normal_lx")),
                                 "u": finite_float(event.get("u_lx"))})
        elif kind == "adaptive_batch" and isinstance(event.get("points"), list):
            self.batch_points += len(event["points"])      # an adaptive campaign's plan grows batch by batch
        elif kind in ("lamp_on", "warmup_stable", "warmup_not_stable"):
            self.changes.append({"k": "l", "t": rig_s, "i": finite_float(event.get("current_a")),
                                 "v": finite_float(event.get("voltage_v", event.get("lamp_voltage_v")))})
        self._at(event.get("time_utc"), rig_s)
        self._phase(kind, event, rig_s)
        if kind not in QUIET_EVENTS:
            self.changes.append({"k": "ev", "utc": event.get("time_utc"), "t": rig_s, "event": kind,
                                 "text": summarize_event(event)})

    def _at(self, time_utc: Any, rig_s: float | None) -> None:
        """The run's latest time, wall and rig."""
        wall = _utc_s(time_utc)
        if wall is not None:
            self.last_utc = str(time_utc)
        if rig_s is not None:
            self.rig_time_s = rig_s if self.rig_time_s is None else max(self.rig_time_s, rig_s)
            if wall is not None and self.phase == "measuring":
                self.rate_latest = (wall, rig_s)
                if self.rate_origin is None:
                    self.rate_origin = (wall, rig_s)

    def _phase(self, kind: str, event: dict[str, Any], rig_s: float | None) -> None:
        if kind == "resume":                          # a new session: its own rate
            self.session_done, self.rate_origin, self.rate_latest = None, None, None
            self.active_s, self.active_since = 0.0, None
        if kind == "aligned":
            self.aligned = True
        phase = PHASE_AFTER.get(kind)
        if phase is None or (phase == "closing" and self.phase in ("interrupted", "failed")):
            return
        if phase == "measuring" and kind.startswith("warmup") and self._aligning():
            phase = "aligning"
        was_measuring = self.phase == "measuring"
        self.phase = phase
        self.detail = {"paused": f"{event.get('device', '?')}: {event.get('reason', '')}",
                       "stopping": str(event.get("reason", "")), "interrupted": str(event.get("reason", "")),
                       "failed": str(event.get("error", "")),
                       "warm-up": "lamp switched on" if kind == "lamp_on" else ""}.get(phase, "")
        if rig_s is None:
            return
        if was_measuring and phase != "measuring" and self.active_since is not None:
            self.active_s += rig_s - self.active_since
            self.active_since = None
        elif phase == "measuring" and not was_measuring:
            self.active_since = rig_s
            if self.session_done is None:
                self.session_done = self.done

    def _aligning(self) -> bool:
        content = _section(self.manifest, "campaign").get("content")
        return isinstance(content, dict) and content.get("alignment") is not None and not self.aligned

    # -- what the page shows -----------------------------------------------------------------
    @property
    def done(self) -> int:
        return len(self.final | self.pending)

    def state(self) -> tuple[str, str]:
        """(phase, detail): the events' phase, overruled by the manifest once the run has ended, and by
        a writer that is gone while the manifest still says `running` (killed)."""
        if not self.folder.is_dir():
            return "waiting", "the folder does not exist yet (the run creates it)"
        if self.manifest_error:
            return "unreadable", self.manifest_error
        if not self.manifest:
            return "waiting", "no dataset.json yet"
        status = self.manifest.get("status")
        if status in PHASE_OF_STATUS:
            detail = self.manifest.get("error") if status == "failed" else self.detail
            return PHASE_OF_STATUS[status], str(detail or "")
        if status == "running" and writer_alive(self.folder) is False:
            return "abandoned", ("the writing process is gone without closing the folder (killed?); "
                                 "`rig run --resume` continues it")
        return self.phase, self.detail

    def _to_measure(self) -> int | None:
        counts = self.manifest.get("counts") or {}
        if isinstance(counts.get("planned"), int) and isinstance(counts.get("skipped"), int):
            return counts["planned"] - counts["skipped"]
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
        if n <= 0 or active <= 0:
            return eta
        eta["rig_s"] = left_s = max(to_measure - self.done, 0) * active / n
        if self.rate_origin and self.rate_latest and self.rate_latest[1] > self.rate_origin[1]:
            per = (self.rate_latest[0] - self.rate_origin[0]) / (self.rate_latest[1] - self.rate_origin[1])
            eta["wall_per_rig"], eta["wall_s"] = per, left_s * per
        return eta

    def budget(self) -> list[dict]:
        """The uncertainty budget of the points so far (rig.physics.budget, as the manifest has it at the end)."""
        if self._budget is None:
            self._budget = campaign_budget(list(self.budget_rows.values()), BUDGET_COLUMNS)
        return self._budget

    def snapshot(self, since: int = 0) -> dict[str, Any]:
        """Everything the page shows, with the changes from `since` on (0 after a new `generation`)."""
        phase, detail = self.state()
        to_measure = self._to_measure()
        m = self.manifest
        sample, rig = _section(m, "sample"), _section(m, "rig")
        return {
            "folder": str(self.folder), "generation": self.generation, "next": len(self.changes),
            "changes": self.changes[max(since, 0):],
            "now_utc": datetime.now(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z"),
            "last_utc": self.last_utc, "created_utc": m.get("created_utc"), "finished_utc": m.get("finished_utc"),
            "campaign": _section(m, "campaign").get("name"), "sample": sample.get("id"),
            "sample_description": sample.get("description"), "rig": rig.get("name"),
            "simulated": rig.get("simulated"), "software": _section(m, "software").get("version"),
            "status": m.get("status"), "phase": phase, "detail": detail,
            "progress": {"done": self.done, "to_measure": to_measure, "in_csv": len(self.final),
                         "pending": len(self.pending - self.final), "skipped": sum(self.skipped.values())},
            "rig_time_s": self.rig_time_s, "eta": self._eta(phase, to_measure),
            "series": self.plan.series if self.plan else [], "plan_error": self.plan.error if self.plan else None,
            "skipped": [{"reason": r, "count": n, "meaning": describe_reason(r) if r.partition(":")[0] in SKIP_REASONS
                         else ""} for r, n in self.skipped.most_common()],
            "flags": dict(self.flags.most_common()), "budget": self.budget(), "bad_lines": self.bad_lines,
        }
