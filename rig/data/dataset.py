"""The dataset folder (contract: docs/dataset.md), written so no completed point is lost.

brdf.csv rows are appended and fsync'ed as each point completes; events.jsonl
likewise; dataset.json is replaced atomically (temp file, fsync, rename,
fsync of the folder), so a crash at any instant leaves readable files.
"""

from __future__ import annotations

import csv
import errno
import io
import json
import math
import os
import shutil
import sys
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator, Mapping

import numpy as np

from rig.data.folderlock import LOCK_NAME, FolderLock, FolderLockedError
from rig.data.images import write_luminance_exr

FORMAT = "rig-brdf-dataset"
FORMAT_VERSION = "1.0"
#: The manifest's pointer to the angle conventions: a document that ships with rig.
CONVENTIONS = "docs/geometry.md of rig (angle conventions, degrees, phi in [0, 360))"

BRDF_COLUMNS = (
    "point_id", "series", "theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg",
    "brdf_per_sr", "u_brdf_per_sr", "luminance_cd_m2", "u_luminance_cd_m2",
    "illuminance_lx", "illuminance_normal_lx",
    "stage_vertical_deg", "stage_normal_deg", "arm_azimuth_deg", "arm_polar_deg",
    "exposures_s", "saturated_fraction", "flags", "time_utc", "rig_time_s",
    # project columns after the contract's
    "u_illuminance_normal_lx", "roi_std_cd_m2", "n_frames", "capture_time_s",
    # relative uncertainty budget (k = 1), see rig/physics/budget.py
    "u_rel_noise", "u_rel_dark", "u_rel_texture", "u_rel_calibration", "u_rel_illuminance", "u_rel_drift",
    "u_rel_angle",
)
SKIPPED_COLUMNS = ("point_id", "theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg", "reason")


class DatasetError(RuntimeError):
    """The output folder cannot be used, or a dataset folder cannot be read; the message names it."""


class DiskFullError(DatasetError):
    """A write ran out of space (ENOSPC, EDQUOT); the message names the folder and the space needed."""


#: errno values of a full disk or an exhausted quota.
DISK_FULL_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT})
#: Bytes set aside in `.reserve` when a writer opens a folder, freed when the disk fills so that
#: the final events and the manifest (about 10 kB, written twice by the atomic replace) still fit.
RESERVE_BYTES = 64 * 1024
RESERVE_NAME = ".reserve"


def utc_now() -> str:
    return datetime.now(timezone.utc).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def _cell(value: Any) -> str:
    if isinstance(value, (float, np.floating)):
        if not math.isfinite(value):
            raise ValueError(f"refusing to write a non-finite number ({value})")
        return repr(float(value))
    if isinstance(value, (list, tuple)):
        return ";".join(_cell(v) for v in value)
    return str(value)


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
            _write_all(fd, text.encode("utf-8"))
            os.fsync(fd)
        finally:
            os.close(fd)
    except BaseException:
        tmp.unlink(missing_ok=True)      # a full disk must not leave a half-written temp file
        raise
    os.replace(tmp, path)
    _fsync_dir(path.parent)


def _write_all(fd: int, data: bytes) -> None:
    """os.write until every byte is written (a write may be short); the only low-level write of this module."""
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view):]


def _json_default(obj: Any) -> Any:
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    if isinstance(obj, Path):
        return str(obj)
    raise TypeError(f"cannot store {type(obj).__name__} in JSON")


class _AppendLog:
    """A line-oriented file whose every line is on disk before append() returns.

    A failed append (a full disk) is undone by truncating to the previous length, so the file
    never ends in half a line that later lines would be glued to.
    """

    def __init__(self, path: Path):
        self.path = path
        self._fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT | os.O_CLOEXEC, 0o644)
        self._size = os.fstat(self._fd).st_size

    def append(self, line: str) -> None:
        data = line.encode("utf-8")
        try:
            _write_all(self._fd, data)
            os.fsync(self._fd)
        except OSError:
            try:
                os.ftruncate(self._fd, self._size)
            except OSError:
                pass     # nothing better to do; a reader ignores a torn last line
            raise
        self._size += len(data)

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


def _csv_line(values: Iterable[Any]) -> str:
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow([_cell(v) for v in values])
    return buf.getvalue()


def cut_torn_tail(path: Path) -> int:
    """Drop a last line that has no newline: a write cut short by a kill. Returns bytes removed."""
    size = path.stat().st_size
    if size == 0:
        return 0
    with open(path, "rb+") as fh:
        data = fh.read()
        keep = data.rfind(b"\n") + 1
        if keep == size:
            return 0
        fh.truncate(keep)
        fh.flush()
        os.fsync(fh.fileno())
    return size - keep


def require_new_output(path: Path, hint: str = "choose another --out, or continue it with --resume") -> None:
    """DatasetError unless `path` is absent or an empty folder: rig never writes over anything."""
    if not path.exists():
        return
    if not path.is_dir():
        raise DatasetError(f"output {path} exists and is not a folder; choose another --out "
                           "(nothing was overwritten)")
    try:
        occupied = any(p.name != LOCK_NAME for p in path.iterdir())
    except OSError as exc:
        raise DatasetError(f"output folder {path} cannot be read: {exc.strerror or exc}") from None
    if occupied:
        raise DatasetError(f"output folder {path} already exists and is not empty; {hint} (nothing was overwritten)")


@contextmanager
def removed_on_failure(path: Path) -> Iterator[Path]:
    """Run the body that writes the new output `path`; if it fails, remove what it wrote, so a
    refused or failed command leaves nothing behind. `path` must be absent or an empty folder."""
    existed = path.exists()
    try:
        yield path
    except BaseException:
        if not existed and path.is_dir():
            shutil.rmtree(path, ignore_errors=True)
        elif not existed:
            path.unlink(missing_ok=True)
        elif path.is_dir():
            for child in path.iterdir():
                if child.is_dir():
                    shutil.rmtree(child, ignore_errors=True)
                else:
                    child.unlink(missing_ok=True)
        raise


def format_bytes(n: float) -> str:
    for unit in ("bytes", "kB", "MB", "GB"):
        if abs(n) < 1000 or unit == "GB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.1f} {unit}"
        n /= 1000
    raise AssertionError("unreachable")


def folder_size(folder: Path) -> int:
    """Bytes in the files of `folder` and its sub-folders (images/), the lock and the reserve left out."""
    total = 0
    for root, _, files in os.walk(folder):
        for name in files:
            if name not in (LOCK_NAME, RESERVE_NAME):
                try:
                    total += os.stat(os.path.join(root, name)).st_size
                except OSError:
                    pass
    return total


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
        created = _first_missing(self.dir)
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
            self._lock.acquire()
        except FolderLockedError as exc:
            raise DatasetError(str(exc)) from None
        except OSError as exc:
            raise DatasetError(f"output folder {self.dir} is not writable: {exc.strerror or exc}") from None
        try:
            require_new_output(self.dir)     # again under the lock: another writer may have just finished
            self.manifest: dict[str, Any] = {
                "format": FORMAT, "format_version": FORMAT_VERSION, "conventions": CONVENTIONS,
                "created_utc": utc_now(), "status": "running", **manifest}
            self._make_reserve()
            write_json_atomic(self.dir / "dataset.json", self.manifest)
            self._open_logs()
            self._rows.append(_csv_line(BRDF_COLUMNS))
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
        self._rows: _AppendLog | None = None
        self._events: _AppendLog | None = None
        self.disk_full = False
        self.unwritten_rows = 0
        self.n_rows = 0
        self.cut_bytes: dict[str, int] = {}

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
    def reopen(cls, out_dir: str | Path, *, space_needed_bytes: int | None = None) -> "DatasetWriter":
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
        try:
            self._lock.acquire()
        except FolderLockedError as exc:
            raise DatasetError(str(exc)) from None
        except OSError as exc:
            raise DatasetError(f"{self.dir}: cannot lock the folder for writing: {exc.strerror or exc}") from None
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
        self._rows = _AppendLog(self.dir / "brdf.csv")
        self._events = _AppendLog(self.dir / "events.jsonl")

    def _make_reserve(self) -> None:
        """Set RESERVE_BYTES aside (zeros, really allocated) for the records of a full disk."""
        fd = os.open(self.dir / RESERVE_NAME, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_CLOEXEC, 0o644)
        try:
            _write_all(fd, bytes(RESERVE_BYTES))
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
        lines = [_csv_line(SKIPPED_COLUMNS)]
        lines += [_csv_line(getattr(s, c) for c in SKIPPED_COLUMNS) for s in skipped]
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
        missing = [c for c in BRDF_COLUMNS if c not in row]
        if missing:
            raise ValueError(f"row for point {row.get('point_id')} lacks {', '.join(missing)}")
        line = _csv_line(row[c] for c in BRDF_COLUMNS)
        if self._guarded("brdf.csv", lambda: self._rows.append(line)):
            self.n_rows += 1
        else:
            self.unwritten_rows += 1

    def event(self, kind: str, **fields: Any) -> None:
        record = {"time_utc": utc_now(), "event": kind, **fields}
        line = json.dumps(record, default=_json_default) + "\n"
        self._guarded("events.jsonl", lambda: self._events.append(line))

    def update_manifest(self, **changes: Any) -> None:
        """Replace dataset.json with the changes; on a full disk the reserve is freed to make room
        for it, so the manifest can still say how the run ended."""
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
        """`images/<point_id>.exr`; a full disk is a DiskFullError like any other write.

        OpenEXR reports a failed write as RuntimeError with the C library's text, not as OSError.
        """
        path = self.image_path(point_id)

        def write() -> None:
            try:
                write_luminance_exr(path, luminance_cd_m2, metadata)
            except RuntimeError as exc:
                path.unlink(missing_ok=True)
                full = next((e for e in DISK_FULL_ERRNOS if os.strerror(e) in str(exc)), None)
                if full is None:
                    raise
                raise OSError(full, os.strerror(full), str(path)) from None
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


def _first_missing(path: Path) -> Path | None:
    """The outermost folder of `path` that does not exist yet (what mkdir(parents=True) creates)."""
    missing = None
    for p in (path, *path.parents):
        if p.exists():
            break
        missing = p
    return missing


def existing_parent(path: Path) -> Path:
    """`path` or its nearest existing parent (where free space is measured before a folder exists)."""
    for p in (path, *path.absolute().parents):
        if p.exists():
            return p
    return Path("/")


#: Units of the brdf.csv columns, for notebooks and exporters.
UNITS = {
    "theta_i_deg": "deg", "phi_i_deg": "deg", "theta_o_deg": "deg", "phi_o_deg": "deg",
    "brdf_per_sr": "1/sr", "u_brdf_per_sr": "1/sr", "luminance_cd_m2": "cd/m2", "u_luminance_cd_m2": "cd/m2",
    "illuminance_lx": "lx", "illuminance_normal_lx": "lx", "u_illuminance_normal_lx": "lx",
    "stage_vertical_deg": "deg", "stage_normal_deg": "deg", "arm_azimuth_deg": "deg", "arm_polar_deg": "deg",
    "exposures_s": "s", "saturated_fraction": "1", "rig_time_s": "s", "roi_std_cd_m2": "cd/m2",
    "capture_time_s": "s", **{c: "1" for c in BRDF_COLUMNS if c.startswith("u_rel_")},
}
_TEXT_COLUMNS = {"point_id", "flags", "time_utc", "exposures_s"}


@dataclass(frozen=True)
class Dataset:
    """A dataset folder in memory: numeric columns as float arrays, the rest as lists of strings."""

    path: Path
    manifest: dict
    columns: dict[str, np.ndarray]
    point_id: list[str]
    flags: list[tuple[str, ...]]
    skipped: list[dict]
    torn_bytes: int = 0          # bytes of a torn last line of brdf.csv that were ignored

    def __len__(self) -> int:
        return len(self.point_id)

    def __getitem__(self, column: str) -> np.ndarray:
        return self.columns[column]

    def directions(self) -> tuple[np.ndarray, np.ndarray]:
        """(ωi, ωo) as SCS unit vectors (N, 3) from the achieved angles."""
        from rig.physics.geometry import sph_to_vec

        rad = {k: np.radians(self.columns[k]) for k in ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg")}
        return (sph_to_vec(rad["theta_i_deg"], rad["phi_i_deg"]),
                sph_to_vec(rad["theta_o_deg"], rad["phi_o_deg"]))

    def has_flag(self, flag: str) -> np.ndarray:
        return np.array([flag in f for f in self.flags], bool)


_JSON_KINDS = {list: "array", str: "string", int: "number", float: "number", bool: "boolean", type(None): "null"}


def read_manifest(folder: Path, *, purpose: str = "cannot read it") -> dict:
    """dataset.json as a dict; DatasetError naming the file for anything else."""
    path = folder / "dataset.json"
    try:
        text = path.read_text(encoding="utf-8")
    except (FileNotFoundError, NotADirectoryError):
        raise DatasetError(f"{folder}: not a dataset folder (no readable dataset.json); {purpose}") from None
    except UnicodeDecodeError as exc:
        raise DatasetError(f"{path}: not UTF-8 text (byte {exc.start}); {purpose}") from None
    except OSError as exc:
        raise DatasetError(f"{path}: {exc.strerror or exc}; {purpose}") from None
    try:
        manifest = json.loads(text)
    except json.JSONDecodeError as exc:
        raise DatasetError(f"{path}:{exc.lineno}: not valid JSON ({exc.msg}); {purpose}") from None
    except RecursionError:
        raise DatasetError(f"{path}: JSON nested too deeply; {purpose}") from None
    if not isinstance(manifest, dict):
        raise DatasetError(f"{path}: a JSON {_JSON_KINDS.get(type(manifest), 'value')}, not the manifest's object; "
                           f"{purpose}")
    if manifest.get("format") != FORMAT:
        raise DatasetError(f"{path}: format is {str(manifest.get('format'))[:40]!r}, not {FORMAT!r}; {purpose}")
    return manifest


@dataclass(frozen=True)
class BrdfTable:
    """brdf.csv as text: the header, one dict per row, each row's line number, and the bytes of a
    torn last line that were left out."""

    path: Path
    header: list[str]
    rows: list[dict[str, str]]
    lines: list[int]
    torn_bytes: int


def complete_lines(path: Path, data: bytes) -> tuple[str, int]:
    """The text of `data` up to its last newline, and the bytes after it (a torn last line)."""
    keep = data.rfind(b"\n") + 1
    try:
        return data[:keep].decode("utf-8"), len(data) - keep
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise DatasetError(f"{path}:{line}: not UTF-8 text") from None


def read_brdf_table(folder: Path) -> BrdfTable:
    """Read brdf.csv without changing it: a torn last line (a kill mid-write) is left out, not cut;
    a malformed row is a DatasetError naming the file and line."""
    path = folder / "brdf.csv"
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        raise DatasetError(f"{path}: missing (the dataset's measured points)") from None
    except OSError as exc:
        raise DatasetError(f"{path}: {exc.strerror or exc}") from None
    text, torn = complete_lines(path, data)
    reader = csv.reader(io.StringIO(text, newline=""))
    try:
        header = next(reader, None)
        if header is None:
            raise DatasetError(f"{path}: no header line")
        missing = [c for c in BRDF_COLUMNS[:21] if c not in header]
        if missing:
            raise DatasetError(f"{path}:1: missing columns {', '.join(missing)}")
        doubled = sorted({c for c in header if header.count(c) > 1})
        if doubled:
            raise DatasetError(f"{path}:1: column {', '.join(doubled)} given twice")
        rows, lines = [], []
        for values in reader:
            if len(values) != len(header):
                raise DatasetError(f"{path}:{reader.line_num}: {len(values)} fields, the header has {len(header)}")
            rows.append(dict(zip(header, values)))
            lines.append(reader.line_num)
    except csv.Error as exc:
        raise DatasetError(f"{path}:{reader.line_num}: {exc}") from None
    return BrdfTable(path, header, rows, lines, torn)


def _number(table: BrdfTable, k: int, column: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not math.isfinite(value):
        raise DatasetError(f"{table.path}:{table.lines[k]}: column {column}: {text[:40]!r} is not a finite number")
    return value


def numeric_columns(table: BrdfTable) -> dict[str, Any]:
    """Every column but the text ones as a float array, and exposures_s as tuples of floats;
    DatasetError naming the line of a cell that is not a finite number."""
    columns: dict[str, Any] = {}
    for name in table.header:
        if name not in _TEXT_COLUMNS:
            columns[name] = np.array([_number(table, k, name, r[name]) for k, r in enumerate(table.rows)], float)
    columns["exposures_s"] = [tuple(_number(table, k, "exposures_s", x) for x in r["exposures_s"].split(";") if x)
                              for k, r in enumerate(table.rows)]
    return columns


def _read_skipped(folder: Path) -> list[dict]:
    """skipped.csv rows (absent: none); a torn last line is left out like in brdf.csv."""
    path = folder / "skipped.csv"
    try:
        data = path.read_bytes()
    except FileNotFoundError:
        return []
    except OSError as exc:
        raise DatasetError(f"{path}: {exc.strerror or exc}") from None
    text, _ = complete_lines(path, data)
    try:
        return list(csv.DictReader(io.StringIO(text, newline="")))
    except csv.Error as exc:
        raise DatasetError(f"{path}: {exc}") from None


def load(path: str | Path) -> Dataset:
    """Read a dataset folder (brdf.csv, skipped.csv, dataset.json); units in `UNITS`.

    Never changes the folder. A torn last line of brdf.csv (what a kill -9 leaves, and what a
    run in progress may show for an instant) is ignored with a one-line warning on stderr, as
    `--resume` cuts it; anything else malformed is a DatasetError naming the file and line.
    """
    path = Path(path)
    manifest = read_manifest(path)
    table = read_brdf_table(path)
    if table.torn_bytes:
        print(f"rig: warning: {table.path}: ignored a torn last line ({table.torn_bytes} bytes without a "
              "newline: a write cut short)", file=sys.stderr)
    columns = numeric_columns(table)
    return Dataset(path=path, manifest=manifest, columns=columns, point_id=[r["point_id"] for r in table.rows],
                   flags=[tuple(f for f in r["flags"].split(";") if f) for r in table.rows],
                   skipped=_read_skipped(path), torn_bytes=table.torn_bytes)
