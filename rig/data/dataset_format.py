"""The dataset folder's contract (docs/dataset.md): format name, brdf.csv and skipped.csv columns, units.

One place for the names that the writer, the readers, the importer and the tests must agree on.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Iterable
from typing import Any

import numpy as np

from rig.physics.budget import BUDGET_COLUMNS, SPLIT_COLUMNS

#: The budget component added after the split columns (rig.physics.static_texture).
TEXTURE_STATIC = "u_rel_texture_static"

FORMAT = "rig-brdf-dataset"
#: 1.1: empty cells for values that do not apply (NaN when read); column illuminance_interpolated.
#: 1.2: column u_rel_texture_static (the static grain's shared part of the ROI texture), last.
FORMAT_VERSION = "1.2"
#: The manifest's pointer to the angle conventions: a document that ships with rig.
CONVENTIONS = "docs/geometry.md of rig (angle conventions, degrees, phi in [0, 360))"

#: The contract's columns of brdf.csv (docs/dataset.md): every reader needs them, in any order.
CONTRACT_COLUMNS = (
    "point_id", "series", "theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg",
    "brdf_per_sr", "u_brdf_per_sr", "luminance_cd_m2", "u_luminance_cd_m2",
    "illuminance_lx", "illuminance_normal_lx",
    "stage_vertical_deg", "stage_normal_deg", "arm_azimuth_deg", "arm_polar_deg",
    "exposures_s", "saturated_fraction", "flags", "time_utc", "rig_time_s",
)
#: Columns after the contract's: capture details, the relative uncertainty budget (k = 1, rig/physics/budget.py)
#: and whether E⊥ was interpolated between bracketing readings (1) or is the last reading (0); the budget's
#: static-texture component last (added in 1.2).
PROJECT_COLUMNS = ("u_illuminance_normal_lx", "roi_std_cd_m2", "n_frames", "capture_time_s", "filter_position",
                   "filter_transmission", "footprint_deg", "lobe_bias_rel", "lobe_width_deg",
                   *(c for c in BUDGET_COLUMNS if c != TEXTURE_STATIC), "illuminance_interpolated", *SPLIT_COLUMNS,
                   TEXTURE_STATIC)
#: brdf.csv as rig writes it.
BRDF_COLUMNS = CONTRACT_COLUMNS + PROJECT_COLUMNS
SKIPPED_COLUMNS = ("point_id", "theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg", "reason")


class DatasetError(RuntimeError):
    """The output folder cannot be used, or a dataset folder cannot be read; the message names it."""


class DiskFullError(DatasetError):
    """A write ran out of space (ENOSPC, EDQUOT); the message names the folder and the space needed."""


#: Units of the brdf.csv columns, for notebooks and exporters.
UNITS = {
    "theta_i_deg": "deg", "phi_i_deg": "deg", "theta_o_deg": "deg", "phi_o_deg": "deg",
    "brdf_per_sr": "1/sr", "u_brdf_per_sr": "1/sr", "luminance_cd_m2": "cd/m2", "u_luminance_cd_m2": "cd/m2",
    "illuminance_lx": "lx", "illuminance_normal_lx": "lx", "u_illuminance_normal_lx": "lx",
    "stage_vertical_deg": "deg", "stage_normal_deg": "deg", "arm_azimuth_deg": "deg", "arm_polar_deg": "deg",
    "exposures_s": "s", "saturated_fraction": "1", "rig_time_s": "s", "roi_std_cd_m2": "cd/m2",
    "capture_time_s": "s", "filter_transmission": "1",
    "footprint_deg": "deg", "lobe_bias_rel": "1", "lobe_width_deg": "deg", **dict.fromkeys(BUDGET_COLUMNS, "1"),
    **dict.fromkeys(SPLIT_COLUMNS, "1/sr"),
}
#: brdf.csv columns that are not numbers.
TEXT_COLUMNS = {"point_id", "flags", "time_utc", "exposures_s"}
#: Numeric columns every row must fill; any other numeric cell may be empty where it does not apply
#: (an imported dataset's axis positions, or its u_brdf_per_sr when the source gave none): NaN when read.
REQUIRED_NUMBER_COLUMNS = ("series", "theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg", "brdf_per_sr")
#: Numeric columns holding whole numbers, and the 0/1 ones (for typed readers such as `Dataset.to_frame`).
INTEGER_COLUMNS = ("series", "n_frames", "filter_position")
BOOLEAN_COLUMNS = ("illuminance_interpolated",)


def usable_u(u: np.ndarray) -> np.ndarray:
    """Rows whose u_brdf_per_sr can weight a fit or bound an ALTA segment: finite and > 0 (an empty
    cell, NaN, is a u that does not apply; 0 would claim an exact value)."""
    u = np.asarray(u, float)
    with np.errstate(invalid="ignore"):
        return np.isfinite(u) & (u > 0)


def _cell(value: Any) -> str:
    """A csv cell: floats at full precision (repr reads back exactly), lists `;`-joined, None (does not
    apply) empty, never NaN or inf."""
    if value is None:
        return ""
    if isinstance(value, (float, np.floating)):
        if not math.isfinite(value):
            raise ValueError(f"refusing to write a non-finite number ({value})")
        return repr(float(value))
    if isinstance(value, (list, tuple)):
        return ";".join(_cell(v) for v in value)
    return str(value)


def csv_line(values: Iterable[Any]) -> str:
    """One line of brdf.csv or skipped.csv, newline included."""
    buf = io.StringIO()
    csv.writer(buf, lineterminator="\n").writerow([_cell(v) for v in values])
    return buf.getvalue()
