"""`rig export`: a dataset folder → ALTA, a plain CSV, road-lighting quantities per point (Radiance:
rig.data.radiance; road-lighting quantities at the standard geometries: rig.analysis.road).

Formats (ALTA's text format; CIE / EN 1436 road-lighting quantities):
- `alta`: one text file, `#DIM 4 1`, `#PARAM_IN SPHERICAL_TL_PL_TV_PV` (θi, φi, θo, φo
  in radians; light = our incident direction, view = our viewing direction, both
  pointing away from the surface), `#PARAM_OUT INV_STERADIAN`, `#VS 1` whose column
  is k·u(f) (k given, default 1, and stated in a comment), `#VS 0` when a row has no
  usable u (`export_alta`). Values at full double precision: the file reads back exactly.
- `csv`: one row per point, units in the column names.
- `rl`: road-lighting quantities per point, each *at the measured geometry* (the
  definitions of EN 1436 and CIE 144 r-tables applied to the point's own angles;
  the standard geometries — R_L at θi 88.76°, θo 87.71°; Qd; the r-table at θo 89°;
  Q0, S1 — need a predictor: rig.analysis.road):
  q = L/E = f_r [sr⁻¹] (E on the surface, directional light);
  L/E⊥ = f_r·cos θi, written in mcd·m⁻²·lx⁻¹ (R_L's definition, EN 1436);
  q·cos³γ written ×10⁴ (r's definition, CIE r-tables), with γ (the measurement note's ε)
  the angle of the light from the normal, γ = θi;
  tan γ = tan θi; β = 180° − |φo − φi| (wrapped to [0°, 180°]): the angle between
  the vertical plane through the light and the one through the observer, 0° when
  the luminaire is ahead of the observer beyond the point (forward scattering),
  180° when it is behind the observer (retroreflection); left empty where an
  azimuth is undefined (θi or θo below `POLE_DEG`);
  observation angle = the angle between ωi and ωo (CIE 54 retroreflection).
  Uncertainties: the relative u(f) carried over to q, R_L and r (conservative
  for R_L, which does not depend on the θi in f's budget).
"""

from __future__ import annotations

import csv
import math
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from rig import __version__
from rig.data.alta import write_alta
from rig.data.dataset_format import usable_u
from rig.data.dataset_reader import Dataset, load
from rig.data.output_folder import new_file
from rig.physics.geometry import angle_between, sph_to_vec, wrap_pi

FORMATS = ("alta", "csv", "rl")
#: Within this polar angle (degrees) of the normal an azimuth, hence β, is not meaningful
#: (achieved angles scatter by ~0.01° around a requested normal incidence).
POLE_DEG = 0.1
ANGLE_COLUMNS = ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg")


class ExportError(RuntimeError):
    """The export cannot be written; the message names the path."""


def _refuse_existing(path: Path) -> None:
    if path.exists() and (not path.is_dir() or any(path.iterdir())):
        raise ExportError(f"{path} already exists; choose another --out (nothing was overwritten)")


def _angles_rad(ds: Dataset) -> np.ndarray:
    return np.radians(np.stack([ds[c] for c in ANGLE_COLUMNS], axis=1))


def export_alta(ds: Dataset, out: Path, coverage_k: float = 1.0) -> list[Path]:
    """One ALTA file; `#VS 1` with half-width k·u(f_r) when every row has a usable u, else `#VS 0`.

    ALTA's fitters take the segment [f − k·u, f + k·u] as a hard bound, so k is the user's choice
    (`coverage_k`) and is written in a comment that `rig import` reads back. One row without a
    usable u (finite, > 0: `rig.data.dataset_format.usable_u`) makes the whole file `#VS 0`, said in a
    comment: ALTA has one #VS per file, a zero half-width would be an exact constraint, and a u
    invented for that row would be a false one; ALTA gives `#VS 0` points its `--dt` segment.
    """
    if not (math.isfinite(coverage_k) and coverage_k > 0):
        raise ExportError(f"coverage factor k must be a positive number, got {coverage_k}")
    u = ds["u_brdf_per_sr"]
    missing = int(np.count_nonzero(~usable_u(u)))
    columns = "f_r [1/sr]" + (f", {coverage_k:g}·u(f_r) [1/sr]" if not missing else "")
    comments = [f"exported by rig {__version__} from {ds.path}",
                f"columns: theta_i phi_i theta_o phi_o [rad] (rig SCS, directions away from the surface), {columns}"]
    if missing:
        comments.append(f"#VS 0: {missing} of {len(ds)} rows have no usable u(f_r), so no row's is written "
                        "(ALTA then applies its --dt segment to every point)")
    return [write_alta(out, _angles_rad(ds), ds["brdf_per_sr"], param_in="SPHERICAL_TL_PL_TV_PV",
                       param_out="INV_STERADIAN", ci=None if missing else coverage_k * u,
                       coverage_k=None if missing else coverage_k, header={"SAMPLE": f'"{ds.sample_id()}"'},
                       comments=comments)]


def _write_table(out: Path, header: list[str], columns: list) -> list[Path]:
    with open(out, "w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(header)
        writer.writerows(zip(*columns))
    return [out]


#: Leading columns of the csv and rl tables.
POINT_HEADER = ["point_id", "series", "theta_i [deg]", "phi_i [deg]", "theta_o [deg]", "phi_o [deg]"]


def _point_columns(ds: Dataset) -> list[list]:
    return [ds.point_id, [int(s) for s in ds["series"]], *(ds[c].tolist() for c in ANGLE_COLUMNS)]


def _flags(ds: Dataset) -> list[str]:
    return [";".join(f) for f in ds.flags]


def export_csv(ds: Dataset, out: Path) -> list[Path]:
    header = [*POINT_HEADER, "f_r [1/sr]", "u(f_r) [1/sr]", "flags"]
    u = ["" if math.isnan(v) else v for v in ds["u_brdf_per_sr"].tolist()]     # empty: no u applies
    return _write_table(out, header, [*_point_columns(ds), ds["brdf_per_sr"].tolist(), u, _flags(ds)])


def measured_road_quantities(theta_i_deg: ArrayLike, phi_i_deg: ArrayLike, theta_o_deg: ArrayLike,
                             phi_o_deg: ArrayLike, f: ArrayLike, u: ArrayLike) -> dict[str, np.ndarray]:
    """q, R_L, r at the given (measured) geometries with uncertainties, β, tan γ, observation angle.

    Definitions in the module docstring; the standard geometries are rig.analysis.road's.
    β is NaN where an azimuth is undefined.
    """
    ti, pi_, to, po = (np.radians(np.asarray(a, float)) for a in (theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg))
    f, u = np.asarray(f, float), np.asarray(u, float)
    cos_i = np.cos(ti)
    dphi = np.degrees(np.abs(wrap_pi(po - pi_)))
    pole = (np.degrees(ti) < POLE_DEG) | (np.degrees(to) < POLE_DEG)
    return {
        "q": f, "u_q": u,
        "R_L_mcd": 1e3 * f * cos_i, "u_R_L_mcd": 1e3 * u * cos_i,
        "r_1e4": 1e4 * f * cos_i ** 3, "u_r_1e4": 1e4 * u * cos_i ** 3,
        "beta_deg": np.where(pole, np.nan, 180.0 - dphi),
        "tan_gamma": np.tan(ti),
        "observation_angle_deg": np.degrees(angle_between(sph_to_vec(ti, pi_), sph_to_vec(to, po))),
    }


#: measured_road_quantities keys → rl table columns (NaN written as an empty cell); "at measured geometry":
#: not the standard quantities, which are defined at fixed geometries (rig.analysis.road).
RL_COLUMNS = {
    "q": "q at measured geometry [1/sr]", "u_q": "u(q at measured geometry) [1/sr]",
    "R_L_mcd": "R_L at measured geometry [mcd/m2/lx]", "u_R_L_mcd": "u(R_L at measured geometry) [mcd/m2/lx]",
    "r_1e4": "r at measured geometry [1e-4/sr]", "u_r_1e4": "u(r at measured geometry) [1e-4/sr]",
    "beta_deg": "beta [deg]", "tan_gamma": "tan_gamma [1]", "observation_angle_deg": "observation_angle [deg]",
}


def export_rl(ds: Dataset, out: Path) -> list[Path]:
    theta_i, phi_i, theta_o, phi_o = (ds[c] for c in ANGLE_COLUMNS)
    rq = measured_road_quantities(theta_i, phi_i, theta_o, phi_o, ds["brdf_per_sr"], ds["u_brdf_per_sr"])
    values = [["" if np.isnan(v) else v for v in rq[key].tolist()] for key in RL_COLUMNS]
    return _write_table(out, [*POINT_HEADER, *RL_COLUMNS.values(), "flags"],
                        [*_point_columns(ds), *values, _flags(ds)])


EXPORTERS: dict[str, Callable[[Dataset, Path], list[Path]]] = {
    "alta": export_alta, "csv": export_csv, "rl": export_rl}


def export(dataset: Dataset | str | os.PathLike, fmt: str, out: str | os.PathLike, *,
           coverage_k: float = 1.0) -> list[Path]:
    """Write `dataset` in format `fmt` to the file `out`; returns the files written. `coverage_k`: ALTA's
    segment half-width is k·u.

    Refuses to overwrite an existing file or a non-empty folder.
    """
    if fmt not in EXPORTERS:
        raise ValueError(f"unknown export format {fmt!r}; known: {', '.join(FORMATS)}")
    ds = dataset if isinstance(dataset, Dataset) else load(Path(dataset))
    out = Path(out)
    _refuse_existing(out)
    if len(ds) == 0:
        raise ExportError(f"{ds.path}: no measured point to export")
    with new_file(out) as tmp:           # written under a temporary name, named when complete
        export_alta(ds, tmp, coverage_k) if fmt == "alta" else EXPORTERS[fmt](ds, tmp)
    return [out]
