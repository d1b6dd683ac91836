"""Writing the dataset folder (contract: docs/dataset.md) so that no completed point is lost.

brdf.csv rows are appended and fsync'ed as each point completes; events.jsonl
likewise (a point written ahead, `point_pending`, is fsync'ed behind: `event_synced_behind`);
dataset.json is replaced atomically (temp file, fsync, rename, fsync of the folder), so a
crash at any instant leaves readable files.
"""

from __future__ import annotations

import errno
import json
import os
import shutil
from collections.abc import Callable, Iterable, Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np

from rig.data import append_log
from rig.data.append_log import AppendLog
from rig.data.dataset_format import (
    BRDF_COLUMNS,
    CONVENTIONS,
    FORMAT,
    FORMAT_VERSION,
    SKIPPED_COLUMNS,
    DatasetError,
    DiskFullError,
    csv_line,
)
from rig.data.dataset_reader import cut_torn_tail, read_manifest
from rig.data.folderlock import FolderLock, FolderLockedError
from rig.data.images import write_luminance_exr
from rig.data.output_folder import (
    RESERVE_BYTES,
    RESERVE_NAME,
    existing_parent,
    first_missing,
    folder_size,
    format_bytes,
    require_new_output,
)
from rig.physics.budget import mark_not_stated, not_stated

#: errno values of a full disk or an exhausted quota.
DISK_FULL_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT})


def utc_now() -> str:
    return datetime.now(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def _fsync_dir(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def write_json_atomic(path: Path, data: Mapping[str, Any]) -> None:
    """Replace `path` by `data` so that a crash leaves either the old or the new file, never a mix."""
    tmp = path.with_name(path.name + ".tmp")
    text = json.dumps(data, indent=2, sort_keys=False, default=_json_default) + "\n"
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_CLOEXEC, 0o644)
        try:
            append_log.write_all(fd, text.encode("utf-8"))
            os.fsync(fd)
        finally:
            os.close(fd)
    except BaseException:
        tmp.unlink(missing_ok=True)      # a full disk must not leave a half-written temp file
        raise
    os.replace(tmp, path)
    _fsync_dir(path.parent)


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"cannot store {type(obj).__name__} in JSON")


def _append(log: AppendLog | None, line: str, *, sync_behind: bool = False) -> None:
    """Append to a writer's log; its logs are open from the constructor (or `reopen`) until `close`."""
    if log is None:
        raise RuntimeError("the dataset writer's files are not open")
    log.append(line, sync_behind=sync_behind)


class DatasetWriter:
    """Creates a new dataset folder and appends to it; refuses to touch an existing dataset
    (`reopen` continues one, for a resume).

    One writer per folder: an exclusive lock (rig/data/folderlock.py) is held from the constructor
    (or `reopen`) until `close()`; a second writer gets DatasetError naming the holder.

    A full disk: the first write that fails with ENOSPC/EDQUOT raises DiskFullError and frees
    the `.reserve` file; from then on every write (`append_row`, `event`, `update_manifest`,
    `close`) is best-effort and never raises, so the run's exit path can make the rig safe and
    record `failed`. Rows that could not be written are counted in `unwritten_rows`; they are not
    in brdf.csv, so `--resume` measures them again.

    `space_needed_bytes`: the estimated size of the finished dataset (rig/acquisition/diskspace.py), for the
    message of a full disk.
    """

    def __init__(self, out_dir: str | Path, manifest: Mapping[str, Any], *,
                 space_needed_bytes: int | None = None):
        self._init_state(out_dir, space_needed_bytes)
        require_new_output(self.dir)
        created = first_missing(self.dir)
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise DatasetError(f"output folder {self.dir} is not writable: {exc.strerror or exc}") from None
        self._take_lock(f"output folder {self.dir} is not writable")
        try:
            require_new_output(self.dir)     # again under the lock: another writer may have just finished
            self.manifest: dict[str, Any] = {
                "format": FORMAT, "format_version": FORMAT_VERSION, "conventions": CONVENTIONS,
                "created_utc": utc_now(), "status": "running", **manifest}
            self._make_reserve()
            write_json_atomic(self.dir / "dataset.json", self.manifest)
            self._open_logs()
            _append(self._rows, csv_line(BRDF_COLUMNS))
        except BaseException as exc:
            if isinstance(exc, DatasetError):
                self._abandon()          # another writer filled the folder meanwhile: it is theirs
            else:
                self._abandon(remove=created, own_files=True)
            if isinstance(exc, OSError) and exc.errno in DISK_FULL_ERRNOS:
                raise DiskFullError(f"output folder {self.dir}: no space to start the dataset "
                                    f"({self._space_note()}); nothing was written") from None
            if isinstance(exc, OSError):
                raise DatasetError(f"output folder {self.dir} is not writable: {exc.strerror or exc}") from None
            raise

    def _init_state(self, out_dir: str | Path, space_needed_bytes: int | None) -> None:
        self.dir = Path(out_dir)
        self.space_needed_bytes = space_needed_bytes
        self._lock = FolderLock(self.dir)
        self._rows: AppendLog | None = None
        self._events: AppendLog | None = None
        self.disk_full = False
        self.unwritten_rows = 0
        self.n_rows = 0
        self.cut_bytes: dict[str, int] = {}

    def _take_lock(self, cannot: str) -> None:
        """Lock the folder; DatasetError naming the holder, or `cannot` and the system's reason."""
        try:
            self._lock.acquire()
        except FolderLockedError as exc:
            raise DatasetError(str(exc)) from None
        except OSError as exc:
            raise DatasetError(f"{cannot}: {exc.strerror or exc}") from None

    def _abandon(self, *, remove: Path | None = None, own_files: bool = False) -> None:
        """Undo a start that failed: close, remove what this writer made, unlock.

        `remove`: the outermost folder this writer created (removed whole); else with `own_files`
        the files it wrote into the empty folder it found are removed (the lock file stays).
        """
        self._close_logs()
        if remove is not None:
            shutil.rmtree(remove, ignore_errors=True)
        elif own_files:
            for name in ("dataset.json", "dataset.json.tmp", "brdf.csv", "events.jsonl", RESERVE_NAME):
                (self.dir / name).unlink(missing_ok=True)
        self._lock.release()

    @classmethod
    def reopen(cls, out_dir: str | Path, *, space_needed_bytes: int | None = None) -> DatasetWriter:
        """Continue an existing dataset: lock it, cut torn last lines (a kill mid-write), append.

        Nothing is written unless the folder is a dataset with brdf.csv and events.jsonl, and the
        lock is taken before anything is cut.
        """
        self = cls.__new__(cls)
        self._init_state(out_dir, space_needed_bytes)
        read_manifest(self.dir, purpose="cannot resume")
        for name in ("brdf.csv", "events.jsonl"):
            if not (self.dir / name).is_file():
                raise DatasetError(f"{self.dir / name}: missing, so the folder cannot be resumed "
                                   "(it holds the measured points and the run's log)")
        self._take_lock(f"{self.dir}: cannot lock the folder for writing")
        try:
            self.manifest = read_manifest(self.dir, purpose="cannot resume")   # as it is now, under the lock
            self.cut_bytes = {name: cut_torn_tail(self.dir / name) for name in ("brdf.csv", "events.jsonl")}
            self._make_reserve()
            self._open_logs()
            self.n_rows = max((self.dir / "brdf.csv").read_bytes().count(b"\n") - 1, 0)
        except BaseException as exc:
            self._abandon()
            if isinstance(exc, OSError):
                raise DatasetError(f"{self.dir}: cannot resume: {exc.strerror or exc} "
                                   f"({exc.filename or 'the folder'})") from None
            raise
        return self

    def _open_logs(self) -> None:
        self._rows = AppendLog(self.dir / "brdf.csv")
        self._events = AppendLog(self.dir / "events.jsonl")

    def _make_reserve(self) -> None:
        """Set RESERVE_BYTES aside (zeros, really allocated) for the records of a full disk."""
        fd = os.open(self.dir / RESERVE_NAME, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_CLOEXEC, 0o644)
        try:
            append_log.write_all(fd, bytes(RESERVE_BYTES))
            os.fsync(fd)
        finally:
            os.close(fd)

    def _free_reserve(self) -> None:
        (self.dir / RESERVE_NAME).unlink(missing_ok=True)

    def _space_note(self) -> str:
        try:
            free = shutil.disk_usage(self.dir if self.dir.exists() else existing_parent(self.dir)).free
        except OSError:
            free = 0
        note = f"{format_bytes(free)} free"
        if self.space_needed_bytes is not None:
            written = folder_size(self.dir) if self.dir.exists() else 0
            note += f", about {format_bytes(max(self.space_needed_bytes - written, 0))} more needed to finish"
        return note

    def _guarded(self, what: str, action: Callable[[], None]) -> bool:
        """Run a write. The first full disk raises DiskFullError; after it, failures are swallowed.

        Returns whether the write happened.
        """
        if self.disk_full:
            try:
                action()
                return True
            except OSError:
                return False
        try:
            action()
            return True
        except OSError as exc:
            if exc.errno not in DISK_FULL_ERRNOS:
                raise
            self.disk_full = True
            note = self._space_note()
            self._free_reserve()
            raise DiskFullError(f"{self.dir}: the disk is full (writing {what}; {note}); "
                                f"free some space or move the folder, then continue with: "
                                f"rig run --resume {self.dir}") from None

    def write_skipped(self, skipped: Iterable[Any]) -> None:
        lines = [csv_line(SKIPPED_COLUMNS)]
        lines += [csv_line(getattr(s, c) for c in SKIPPED_COLUMNS) for s in skipped]
        path = self.dir / "skipped.csv"
        tmp = path.with_name(path.name + ".tmp")

        def write() -> None:
            try:
                tmp.write_text("".join(lines), encoding="utf-8")
            except OSError:
                tmp.unlink(missing_ok=True)
                raise
            os.replace(tmp, path)
        self._guarded("skipped.csv", write)

    def append_row(self, row: Mapping[str, Any]) -> None:
        self.append_rows([row])

    def append_rows(self, rows: Sequence[Mapping[str, Any]]) -> None:
        """Append rows to brdf.csv in one write and one fsync: all of them are on disk when this returns, or
        none (a failed write is truncated away, and its rows count as unwritten once the disk is full).

        One fsync per batch, not per row: the rows that an E⊥ reading brackets arrive together, and an
        fsync costs milliseconds (it was the largest share of the pipeline's time per point)."""
        for row in rows:
            missing = [c for c in BRDF_COLUMNS if c not in row]
            if missing:
                raise ValueError(f"row for point {row.get('point_id')} lacks {', '.join(missing)}")
        if not rows:
            return
        text = "".join(csv_line(row[c] for c in BRDF_COLUMNS) for row in rows)
        if self._guarded("brdf.csv", lambda: _append(self._rows, text)):
            self.n_rows += len(rows)
        else:
            self.unwritten_rows += len(rows)

    def event(self, kind: str, **fields: Any) -> None:
        """Append an event to events.jsonl; it is on disk when this returns."""
        self._event(kind, fields, sync_behind=False)

    def event_synced_behind(self, kind: str, **fields: Any) -> None:
        """Append an event that is written when this returns and fsync'ed on a background thread (`AppendLog.append`):
        for the record of every point (`point_pending`), where a synchronous fsync cost the pipeline milliseconds a
        point. A killed process loses nothing; a power cut at most this record (its point is measured again on
        resume), never one written after it. A failed fsync raises at the next write (DiskFullError alike)."""
        self._event(kind, fields, sync_behind=True)

    def _event(self, kind: str, fields: Mapping[str, Any], *, sync_behind: bool) -> None:
        record = {"time_utc": utc_now(), "event": kind, **fields}
        line = json.dumps(record, default=_json_default) + "\n"
        self._guarded("events.jsonl", lambda: _append(self._events, line, sync_behind=sync_behind))

    def update_manifest(self, **changes: Any) -> None:
        """Replace dataset.json with the changes; on a full disk the reserve is freed to make room
        for it, so the manifest can still say how the run ended. An uncertainty budget names there the
        calibrations whose u the rig file did not state (rig.physics.budget.mark_not_stated)."""
        if "uncertainty_budget" in changes:
            changes["uncertainty_budget"] = mark_not_stated(changes["uncertainty_budget"], not_stated(self.manifest))
        self.manifest.update(changes)
        path = self.dir / "dataset.json"

        def write() -> None:
            write_json_atomic(path, self.manifest)
        if not self.disk_full:
            try:
                write()
                return
            except OSError as exc:
                if exc.errno not in DISK_FULL_ERRNOS:
                    raise
                self._free_reserve()     # make room for the manifest, then try once more
        self._guarded("dataset.json", write)

    def image_path(self, point_id: str) -> Path:
        folder = self.dir / "images"
        folder.mkdir(exist_ok=True)
        return folder / f"{point_id}.exr"

    def write_image(self, point_id: str, luminance_cd_m2: np.ndarray, metadata: Mapping[str, Any]) -> None:
        """`images/<point_id>.exr`; a full disk is a DiskFullError like any other write, and leaves no part of
        the image behind."""
        path = self.image_path(point_id)

        def write() -> None:
            try:
                write_luminance_exr(path, luminance_cd_m2, metadata)
            except OSError:
                path.unlink(missing_ok=True)
                raise
        self._guarded(f"images/{point_id}.exr", write)

    def _close_logs(self) -> None:
        for log in (self._rows, self._events):
            if log is not None:
                log.close()

    def close(self) -> None:
        """Close the files, drop the reserve and release the lock; never raises."""
        self._close_logs()
        try:
            self._free_reserve()
        except OSError:
            pass
        self._lock.release()
