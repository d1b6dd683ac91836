"""Reading a dataset folder (docs/dataset.md) without changing it: `load`, and the pieces a resume reuses
(it alone cuts a torn last line, `cut_torn_tail`, before appending)."""

from __future__ import annotations

import csv
import io
import math
import os
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rig.core.jsonfile import JsonFileError, decode_utf8, json_kind, parse_json
from rig.data.dataset_format import (
    BOOLEAN_COLUMNS,
    CONTRACT_COLUMNS,
    FORMAT,
    INTEGER_COLUMNS,
    REQUIRED_NUMBER_COLUMNS,
    TEXT_COLUMNS,
    UNITS,
    DatasetError,
)
from rig.physics.geometry import mean_direction_deg, sph_to_vec

if TYPE_CHECKING:
    import pandas as pd  # type: ignore[import-untyped, unused-ignore]


@dataclass(frozen=True)
class Dataset:
    """A dataset folder in memory: numeric columns as float arrays (NaN where a cell is empty: the value
    does not apply), the rest as lists of strings."""

    path: Path
    manifest: dict
    columns: dict[str, np.ndarray]
    point_id: list[str]
    flags: list[tuple[str, ...]]
    time_utc: list[str]
    skipped: list[dict]
    header: tuple[str, ...]      # brdf.csv's columns in the file's order
    torn_bytes: int = 0          # bytes of a torn last line of brdf.csv that were ignored

    def __len__(self) -> int:
        return len(self.point_id)

    def __getitem__(self, column: str) -> np.ndarray:
        return self.columns[column]

    def directions(self) -> tuple[np.ndarray, np.ndarray]:
        """(ωi, ωo) as SCS unit vectors (N, 3) from the achieved angles."""
        rad = {k: np.radians(self.columns[k]) for k in ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg")}
        return (sph_to_vec(rad["theta_i_deg"], rad["phi_i_deg"]),
                sph_to_vec(rad["theta_o_deg"], rad["phi_o_deg"]))

    def series_incidence_deg(self, series: int) -> tuple[float, float]:
        """Mean achieved incidence (θi, φi) of a series, degrees (φ in [0, 360)): direction of the mean ωi."""
        rows = self.columns["series"] == series
        return mean_direction_deg(self.columns["theta_i_deg"][rows], self.columns["phi_i_deg"][rows])

    def sample_id(self) -> str:
        """The manifest's sample id, else the folder's name: what figures and exports call the sample."""
        return str((self.manifest.get("sample") or {}).get("id") or self.path.name)

    def has_flag(self, flag: str) -> np.ndarray:
        return np.array([flag in f for f in self.flags], bool)

    def to_frame(self) -> pd.DataFrame:
        """brdf.csv as a pandas DataFrame, one row per point, in the file's column order.

        dtypes: numbers float64 with NaN for empty cells; `series`, `n_frames`, `filter_position`
        nullable Int64; `illuminance_interpolated` nullable boolean; `point_id` and `flags`
        (`;`-joined, "" when clean) strings; `time_utc` datetime64 UTC; `exposures_s` tuples of
        floats. `frame.attrs` holds `units` (rig.data.dataset_format.UNITS) and the `manifest`.
        Needs pandas (the optional extra `pandas`); ImportError saying so without it.
        """
        try:
            import pandas as pd  # type: ignore[import-untyped, unused-ignore]
        except ImportError:
            raise ImportError("Dataset.to_frame and load_frame need pandas: pip install 'rig[pandas]' "
                              "(or pip install pandas)") from None
        data: dict[str, Any] = {}
        for name, values in self.columns.items():
            if name in INTEGER_COLUMNS:
                data[name] = pd.array([None if np.isnan(v) else int(v) for v in values], dtype="Int64")
            elif name in BOOLEAN_COLUMNS:
                data[name] = pd.array([None if np.isnan(v) else bool(v) for v in values], dtype="boolean")
            elif name == "exposures_s":
                data[name] = pd.Series(values, dtype=object)
            else:
                data[name] = values
        data["point_id"] = pd.array(self.point_id, dtype="string")
        data["flags"] = pd.array([";".join(f) for f in self.flags], dtype="string")
        data["time_utc"] = pd.to_datetime(self.time_utc, utc=True, format="ISO8601")
        frame = pd.DataFrame({c: data[c] for c in self.header})
        frame.attrs["units"] = {c: UNITS[c] for c in self.header if c in UNITS}
        frame.attrs["manifest"] = self.manifest
        return frame


#: Manifest entries that readers look into (docs/dataset.md): each an object where present (null: not recorded).
MANIFEST_OBJECTS = ("campaign", "sample", "rig", "software", "counts", "provenance", "simulated_brdf", "alignment",
                    "footprint")


def read_manifest(folder: Path, *, purpose: str = "cannot read it") -> dict:
    """dataset.json as a dict; DatasetError naming the file for anything else."""
    path = folder / "dataset.json"
    try:
        data = path.read_bytes()
    except (FileNotFoundError, NotADirectoryError):
        raise DatasetError(f"{folder}: not a dataset folder (no readable dataset.json); {purpose}") from None
    except OSError as exc:
        raise DatasetError(f"{path}: {exc.strerror or exc}; {purpose}") from None
    try:
        manifest = parse_json(decode_utf8(data, path), path)
    except JsonFileError as exc:
        raise DatasetError(f"{exc}; {purpose}") from None
    if not isinstance(manifest, dict):
        raise DatasetError(f"{path}: {json_kind(manifest)}, not the manifest's object; {purpose}")
    if manifest.get("format") != FORMAT:
        raise DatasetError(f"{path}: format is {str(manifest.get('format'))[:40]!r}, not {FORMAT!r}; {purpose}")
    for key in MANIFEST_OBJECTS:
        if not isinstance(manifest.get(key, {}), dict | None):
            raise DatasetError(f"{path}: {key!r} is {json_kind(manifest[key])}, not an object; {purpose}")
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
        missing = [c for c in CONTRACT_COLUMNS if c not in header]
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


def _optional_number(table: BrdfTable, k: int, column: str, text: str) -> float:
    """An empty cell (the value does not apply) as NaN; otherwise `_number`."""
    return math.nan if text == "" else _number(table, k, column, text)


def numeric_columns(table: BrdfTable) -> dict[str, Any]:
    """Every column but the text ones as a float array (NaN for an empty cell, except in
    REQUIRED_NUMBER_COLUMNS), and exposures_s as tuples of floats; DatasetError naming the line
    of a cell that is not a finite number."""
    columns: dict[str, Any] = {}
    for name in table.header:
        if name not in TEXT_COLUMNS:
            read = _number if name in REQUIRED_NUMBER_COLUMNS else _optional_number
            columns[name] = np.array([read(table, k, name, r[name]) for k, r in enumerate(table.rows)], float)
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
                   time_utc=[r["time_utc"] for r in table.rows], skipped=_read_skipped(path),
                   header=tuple(table.header), torn_bytes=table.torn_bytes)


def load_frame(path: str | Path) -> pd.DataFrame:
    """`load(path).to_frame()`: a dataset folder's brdf.csv as a typed pandas DataFrame (needs pandas)."""
    return load(path).to_frame()
