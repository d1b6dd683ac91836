"""The dataset folder (contract: shared/spec/dataset.md), written so no completed point is lost.

brdf.csv rows are appended and fsync'ed as each point completes; events.jsonl
likewise; dataset.json is replaced atomically (temp file, fsync, rename,
fsync of the folder), so a crash at any instant leaves readable files.
"""

from __future__ import annotations

import csv
import io
import json
import math
import os
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

FORMAT = "rig-brdf-dataset"
FORMAT_VERSION = "1.0"
CONVENTIONS = "shared/spec/geometry.md (rig angle conventions, degrees, phi in [0, 360))"

BRDF_COLUMNS = (
    "point_id", "series", "theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg",
    "brdf_per_sr", "u_brdf_per_sr", "luminance_cd_m2", "u_luminance_cd_m2",
    "illuminance_lx", "illuminance_normal_lx",
    "stage_vertical_deg", "stage_normal_deg", "arm_azimuth_deg", "arm_polar_deg",
    "exposures_s", "saturated_fraction", "flags", "time_utc", "rig_time_s",
    # project columns after the contract's
    "u_illuminance_normal_lx", "roi_std_cd_m2", "n_frames", "capture_time_s",
    # relative uncertainty budget (k = 1), see rig/budget.py
    "u_rel_noise", "u_rel_dark", "u_rel_texture", "u_rel_calibration", "u_rel_illuminance", "u_rel_drift",
    "u_rel_angle",
)
SKIPPED_COLUMNS = ("point_id", "theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg", "reason")


class DatasetError(RuntimeError):
    """The output folder cannot be used; the message names it."""


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
    tmp = path.with_name(path.name + ".tmp")
    with open(tmp, "w", encoding="utf-8") as fh:
        json.dump(data, fh, indent=2, sort_keys=False, default=_json_default)
        fh.write("\n")
        fh.flush()
        os.fsync(fh.fileno())
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


class _AppendLog:
    """A line-oriented file whose every line is on disk before append() returns."""

    def __init__(self, path: Path):
        self.path = path
        self._fh = open(path, "a", encoding="utf-8", newline="")

    def append(self, line: str) -> None:
        self._fh.write(line)
        self._fh.flush()
        os.fsync(self._fh.fileno())

    def close(self) -> None:
        self._fh.close()


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


class DatasetWriter:
    """Creates a new dataset folder and appends to it; refuses to touch an existing dataset
    (`reopen` continues one, for a resume)."""

    def __init__(self, out_dir: str | Path, manifest: Mapping[str, Any]):
        self.dir = Path(out_dir)
        if self.dir.exists() and any(self.dir.iterdir()):
            raise DatasetError(f"output folder {self.dir} already exists and is not empty; "
                               "choose another --out, or continue it with --resume (nothing was overwritten)")
        try:
            self.dir.mkdir(parents=True, exist_ok=True)
            probe = self.dir / ".write-test"
            probe.write_text("")
            probe.unlink()
        except OSError as exc:
            raise DatasetError(f"output folder {self.dir} is not writable: {exc.strerror or exc}") from None
        self.manifest: dict[str, Any] = {
            "format": FORMAT, "format_version": FORMAT_VERSION, "conventions": CONVENTIONS,
            "created_utc": utc_now(), "status": "running", **manifest}
        write_json_atomic(self.dir / "dataset.json", self.manifest)
        self._open_logs()
        self._rows.append(_csv_line(BRDF_COLUMNS))
        self.n_rows = 0

    @classmethod
    def reopen(cls, out_dir: str | Path) -> "DatasetWriter":
        """Continue an existing dataset: torn last lines (a kill mid-write) are cut, then appended to."""
        self = cls.__new__(cls)
        self.dir = Path(out_dir)
        try:
            self.manifest = json.loads((self.dir / "dataset.json").read_text(encoding="utf-8"))
        except (OSError, json.JSONDecodeError) as exc:
            raise DatasetError(f"{self.dir}: cannot resume, no readable dataset.json ({exc})") from None
        if self.manifest.get("format") != FORMAT:
            raise DatasetError(f"{self.dir}: not a {FORMAT} folder")
        self.cut_bytes = {name: cut_torn_tail(self.dir / name) for name in ("brdf.csv", "events.jsonl")}
        self._open_logs()
        with open(self.dir / "brdf.csv", encoding="utf-8") as fh:
            self.n_rows = max(sum(1 for _ in fh) - 1, 0)
        return self

    def _open_logs(self) -> None:
        self._rows = _AppendLog(self.dir / "brdf.csv")
        self._events = _AppendLog(self.dir / "events.jsonl")

    def write_skipped(self, skipped: Iterable[Any]) -> None:
        lines = [_csv_line(SKIPPED_COLUMNS)]
        lines += [_csv_line(getattr(s, c) for c in SKIPPED_COLUMNS) for s in skipped]
        path = self.dir / "skipped.csv"
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text("".join(lines), encoding="utf-8")
        os.replace(tmp, path)

    def append_row(self, row: Mapping[str, Any]) -> None:
        missing = [c for c in BRDF_COLUMNS if c not in row]
        if missing:
            raise ValueError(f"row for point {row.get('point_id')} lacks {', '.join(missing)}")
        self._rows.append(_csv_line(row[c] for c in BRDF_COLUMNS))
        self.n_rows += 1

    def event(self, kind: str, **fields: Any) -> None:
        record = {"time_utc": utc_now(), "event": kind, **fields}
        self._events.append(json.dumps(record, default=_json_default) + "\n")

    def update_manifest(self, **changes: Any) -> None:
        self.manifest.update(changes)
        write_json_atomic(self.dir / "dataset.json", self.manifest)

    def image_path(self, point_id: str) -> Path:
        folder = self.dir / "images"
        folder.mkdir(exist_ok=True)
        return folder / f"{point_id}.exr"

    def close(self) -> None:
        self._rows.close()
        self._events.close()


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

    def __len__(self) -> int:
        return len(self.point_id)

    def __getitem__(self, column: str) -> np.ndarray:
        return self.columns[column]

    def directions(self) -> tuple[np.ndarray, np.ndarray]:
        """(ωi, ωo) as SCS unit vectors (N, 3) from the achieved angles."""
        from rig.geometry import sph_to_vec

        rad = {k: np.radians(self.columns[k]) for k in ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg")}
        return (sph_to_vec(rad["theta_i_deg"], rad["phi_i_deg"]),
                sph_to_vec(rad["theta_o_deg"], rad["phi_o_deg"]))

    def has_flag(self, flag: str) -> np.ndarray:
        return np.array([flag in f for f in self.flags], bool)


def load(path: str | Path) -> Dataset:
    """Read a dataset folder (brdf.csv, skipped.csv, dataset.json); units in `UNITS`."""
    path = Path(path)
    try:
        manifest = json.loads((path / "dataset.json").read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise DatasetError(f"{path}: not a dataset folder (no dataset.json)") from None
    except json.JSONDecodeError as exc:
        raise DatasetError(f"{path / 'dataset.json'}: not valid JSON: {exc}") from None
    if manifest.get("format") != FORMAT:
        raise DatasetError(f"{path / 'dataset.json'}: format is {manifest.get('format')!r}, not {FORMAT!r}")
    with open(path / "brdf.csv", newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        header = reader.fieldnames or []
        missing = [c for c in BRDF_COLUMNS[:21] if c not in header]
        if missing:
            raise DatasetError(f"{path / 'brdf.csv'}: missing columns {', '.join(missing)}")
        rows = list(reader)
    columns: dict[str, np.ndarray] = {}
    for name in header:
        if name in _TEXT_COLUMNS:
            continue
        try:
            columns[name] = np.array([float(r[name]) for r in rows], dtype=float)
        except ValueError as exc:
            raise DatasetError(f"{path / 'brdf.csv'}: column {name}: {exc}") from None
    columns["exposures_s"] = [tuple(float(x) for x in r["exposures_s"].split(";") if x) for r in rows]
    skipped_path = path / "skipped.csv"
    skipped = []
    if skipped_path.exists():
        with open(skipped_path, newline="", encoding="utf-8") as fh:
            skipped = list(csv.DictReader(fh))
    return Dataset(path=path, manifest=manifest, columns=columns, point_id=[r["point_id"] for r in rows],
                   flags=[tuple(f for f in r["flags"].split(";") if f) for r in rows], skipped=skipped)
