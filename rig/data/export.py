"""`rig export`: a dataset folder → ALTA, Radiance pabopto2bsdf input, a plain CSV, road-lighting quantities.

Formats (ALTA's text format; Radiance's pabopto2bsdf input; CIE / EN 1436 road-lighting quantities):
- `alta`: one text file, `#DIM 4 1`, `#PARAM_IN SPHERICAL_TL_PL_TV_PV` (θi, φi, θo, φo
  in radians; light = our incident direction, view = our viewing direction, both
  pointing away from the surface), `#PARAM_OUT INV_STERADIAN`, `#VS 1` whose column
  is u(f) (k = 1). Values at full double precision: the file reads back exactly.
- `radiance`: a folder with one pab-opto "Mountain" file per incidence series for
  `pabopto2bsdf`, degrees: `#intheta`, `#inphi` (the series' mean achieved
  incidence), `#upphi 90` (the sample's y axis is "up", so Radiance applies no
  rotation and its frame is our SCS), `#format: theta phi BSDF`, rows `θo φo f`.
  Radiance's incident vector points toward the source like ours.
- `csv`: one row per point, units in the column names.
- `rl`: road-lighting quantities per point (EN 1436, CIE 144 r-tables):
  q = L/E = f_r [sr⁻¹] (E on the surface, directional light);
  R_L = L/E⊥ = f_r·cos θi, written in mcd·m⁻²·lx⁻¹ (EN 1436);
  r = q·cos³γ written ×10⁴ as in CIE r-tables, with γ (the measurement note's ε)
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
import os
from collections.abc import Callable
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from rig import __version__
from rig.data.alta import write_alta
from rig.data.dataset_reader import Dataset, load
from rig.data.output_folder import removed_on_failure
from rig.physics.geometry import angle_between, sph_to_vec, vec_to_sph, wrap_360, wrap_pi

FORMATS = ("alta", "radiance", "csv", "rl")
#: Within this polar angle (degrees) of the normal an azimuth, hence β, is not meaningful
#: (achieved angles scatter by ~0.01° around a requested normal incidence).
POLE_DEG = 0.1
ANGLE_COLUMNS = ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg")


class ExportError(RuntimeError):
    """The export cannot be written; the message names the path."""


def _refuse_existing(path: Path) -> None:
    if path.exists() and (not path.is_dir() or any(path.iterdir())):
        raise ExportError(f"{path} already exists; choose another --out (nothing was overwritten)")


def _sample_id(ds: Dataset) -> str:
    return str(ds.manifest.get("sample", {}).get("id") or ds.path.name)


def _angles_rad(ds: Dataset) -> np.ndarray:
    return np.radians(np.stack([ds[c] for c in ANGLE_COLUMNS], axis=1))


def export_alta(ds: Dataset, out: Path) -> list[Path]:
    comments = [f"exported by rig {__version__} from {ds.path}",
                ("columns: theta_i phi_i theta_o phi_o [rad] (rig SCS, directions away from the surface), "
                 "f_r [1/sr], u(f_r) [1/sr] (k = 1)")]
    if ds.has_flag("no_uncertainty").any():
        comments.append("u(f_r) = 0 where the source gave no uncertainty (flag no_uncertainty)")
    header = {"SAMPLE": f'"{_sample_id(ds)}"'}
    return [write_alta(out, _angles_rad(ds), ds["brdf_per_sr"], param_in="SPHERICAL_TL_PL_TV_PV",
                       param_out="INV_STERADIAN", ci=ds["u_brdf_per_sr"], header=header, comments=comments)]


def series_incidence_deg(ds: Dataset, series: int) -> tuple[float, float]:
    """Mean achieved incidence (θi, φi) of a series, degrees: direction of the mean ωi."""
    wi, _ = ds.directions()
    theta, phi = vec_to_sph(wi[ds["series"] == series].mean(axis=0))
    return float(np.degrees(theta)), float(wrap_360(np.degrees(phi)))


def export_radiance(ds: Dataset, out: Path) -> list[Path]:
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for s in np.unique(ds["series"]).astype(int):
        rows = ds["series"] == s
        theta_i, phi_i = series_incidence_deg(ds, s)
        lines = [f'#sample_name "{_sample_id(ds)}"', f"#data written by rig {__version__} from {ds.path}",
                 f"#intheta {theta_i:.6f}", f"#inphi {phi_i:.6f}", "#upphi 90",
                 f"#datapoints_in_file: {int(rows.sum())}", "#format: theta phi BSDF"]
        lines += [f"{t!r} {p!r} {f!r}" for t, p, f in
                  zip(ds["theta_o_deg"][rows].tolist(), ds["phi_o_deg"][rows].tolist(),
                      ds["brdf_per_sr"][rows].tolist())]
        path = out / f"series{s:02d}_t{theta_i:05.1f}_p{phi_i:05.1f}.txt"
        path.write_text("\n".join(lines) + "\n", encoding="utf-8")
        paths.append(path)
    return paths


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
    return _write_table(out, header, [*_point_columns(ds), ds["brdf_per_sr"].tolist(),
                                      ds["u_brdf_per_sr"].tolist(), _flags(ds)])


def road_quantities(theta_i_deg: ArrayLike, phi_i_deg: ArrayLike, theta_o_deg: ArrayLike, phi_o_deg: ArrayLike,
                    f: ArrayLike, u: ArrayLike) -> dict[str, np.ndarray]:
    """q, R_L, r with uncertainties, β, tan γ, observation angle (definitions in the module docstring).

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


#: road_quantities keys → rl table columns (NaN written as an empty cell).
RL_COLUMNS = {
    "q": "q [1/sr]", "u_q": "u(q) [1/sr]", "R_L_mcd": "R_L [mcd/m2/lx]", "u_R_L_mcd": "u(R_L) [mcd/m2/lx]",
    "r_1e4": "r [1e-4/sr]", "u_r_1e4": "u(r) [1e-4/sr]", "beta_deg": "beta [deg]", "tan_gamma": "tan_gamma [1]",
    "observation_angle_deg": "observation_angle [deg]",
}


def export_rl(ds: Dataset, out: Path) -> list[Path]:
    theta_i, phi_i, theta_o, phi_o = (ds[c] for c in ANGLE_COLUMNS)
    rq = road_quantities(theta_i, phi_i, theta_o, phi_o, ds["brdf_per_sr"], ds["u_brdf_per_sr"])
    values = [["" if np.isnan(v) else v for v in rq[key].tolist()] for key in RL_COLUMNS]
    return _write_table(out, [*POINT_HEADER, *RL_COLUMNS.values(), "flags"],
                        [*_point_columns(ds), *values, _flags(ds)])


EXPORTERS: dict[str, Callable[[Dataset, Path], list[Path]]] = {
    "alta": export_alta, "radiance": export_radiance, "csv": export_csv, "rl": export_rl}


def export(dataset: Dataset | str | os.PathLike, fmt: str, out: str | os.PathLike) -> list[Path]:
    """Write `dataset` in format `fmt` to `out` (a file; a folder for radiance); returns the files written.

    Refuses to overwrite an existing file or a non-empty folder.
    """
    if fmt not in EXPORTERS:
        raise ValueError(f"unknown export format {fmt!r}; known: {', '.join(FORMATS)}")
    ds = dataset if isinstance(dataset, Dataset) else load(Path(dataset))
    out = Path(out)
    _refuse_existing(out)
    if len(ds) == 0:
        raise ExportError(f"{ds.path}: no measured point to export")
    with removed_on_failure(out):
        return EXPORTERS[fmt](ds, out)
