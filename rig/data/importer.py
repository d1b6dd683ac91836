"""`rig import`: a foreign ALTA text file → a rig dataset folder (docs/dataset.md).

Conventions of an imported dataset (also written into its manifest):
- Angles: the file's angles converted by `rig.data.alta.to_rig`; they are the
  "achieved" angles. Points that cannot be converted go to skipped.csv with the reason.
- series: one per distinct incidence (θi, φi), in order of first appearance;
  point_id `<series>-L<line>` names the source line of the sample.
- u_brdf_per_sr: from #VS when the file has it (rig.data.alta: the segment's
  half-width / k); otherwise empty (NaN when read) with the flag `no_uncertainty`.
- Photometric columns are relative, for E⊥ = 1 lx: illuminance_normal_lx = 1,
  illuminance_lx = cos θi, luminance_cd_m2 = f·cos θi, so f = L / (E⊥ cos θi) still holds.
- Columns that do not apply to a foreign instrument (axis positions, saturation,
  rig clock, and every project column after the contract's) are empty cells, never 0
  (a 0 would pass for a measured value, and a 0 u for an exact one).
- Every row is flagged `imported`; time_utc is the time of the import.
- A file without #PARAM_OUT is taken as INV_STERADIAN_COSINE_FACTOR unless told
  otherwise: that is the case of the CEA gray tape, whose values fall toward the
  horizon like f·cos θV (as the yellow file that declares it) and which Belcour et
  al. 2014 plot as BRDF × cos like every sample.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np

from rig import __version__
from rig.core import events
from rig.data.alta import CONVERSION_SKIP_REASONS, AltaData, RigPoints, read_alta, to_rig
from rig.data.dataset_format import BRDF_COLUMNS
from rig.data.dataset_writer import DatasetWriter, utc_now
from rig.data.output_folder import removed_on_failure, require_new_output
from rig.planning.points import SkippedPoint

MISSING_PARAM_OUT_DEFAULT = "INV_STERADIAN_COSINE_FACTOR"
#: Incidences closer than this (degrees) belong to the same series.
SAME_INCIDENCE_DEG = 1e-6

CONVENTIONS = {
    "point_id": "<series>-L<line of the sample in the source file>",
    "series": "one per distinct incidence (θi, φi), in order of first appearance in the file",
    "u_brdf_per_sr": "from #VS as ALTA reads it (#VS 1: the ± half-width; #VS 2: half the segment "
                     "[y - below, y + above]), divided by the k of a rig coverage comment (else k = 1); "
                     "without #VS empty, flag no_uncertainty",
    "photometry": "relative, for E⊥ = 1 lx: illuminance_normal_lx = 1, illuminance_lx = cos θi, "
                  "luminance_cd_m2 = f·cos θi",
    "not_applicable": "stage/arm axis positions, saturated_fraction, rig_time_s, exposures_s and every "
                      "project column after the contract's (e.g. n_frames, u_rel_*): empty cells",
    "flags": "imported on every row; no_uncertainty when the file has no confidence column",
}


def sha256_file(path: Path) -> str:
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def series_index(theta_i_deg: np.ndarray, phi_i_deg: np.ndarray) -> np.ndarray:
    """Series number of each point: distinct incidences numbered in order of first appearance."""
    key = np.stack([np.round(theta_i_deg / SAME_INCIDENCE_DEG), np.round(phi_i_deg / SAME_INCIDENCE_DEG)], axis=1)
    # at normal incidence the azimuth does not matter
    key[theta_i_deg < SAME_INCIDENCE_DEG, 1] = 0
    _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
    rank = np.argsort(np.argsort(first))
    return rank[inverse.ravel()]


#: Every column the rows below do not set (axis positions, saturation, rig clock, project columns) is empty.
_NOT_APPLICABLE = dict.fromkeys(BRDF_COLUMNS)


def _rows(points: RigPoints, ids: list[str], series: np.ndarray, now: str):
    """brdf.csv rows of the converted points (conventions in the module docstring)."""
    a = points.angles
    for k in np.flatnonzero(points.reason == ""):
        cos_i = float(np.cos(np.radians(a.theta_i_deg[k])))
        f = float(points.brdf[k])
        u = None if points.u_brdf is None else float(points.u_brdf[k])
        yield _NOT_APPLICABLE | {
            "point_id": ids[k], "series": int(series[k]),
            "theta_i_deg": float(a.theta_i_deg[k]), "phi_i_deg": float(a.phi_i_deg[k]),
            "theta_o_deg": float(a.theta_o_deg[k]), "phi_o_deg": float(a.phi_o_deg[k]),
            "brdf_per_sr": f, "u_brdf_per_sr": u,
            "luminance_cd_m2": f * cos_i, "u_luminance_cd_m2": None if u is None else u * cos_i,
            "illuminance_lx": cos_i, "illuminance_normal_lx": 1.0, "exposures_s": [],
            "flags": ["imported"] + (["no_uncertainty"] if points.u_brdf is None else []), "time_utc": now,
        }


def _skipped(points: RigPoints, ids: list[str], series: np.ndarray) -> list[SkippedPoint]:
    a = points.angles
    return [SkippedPoint(ids[k], int(series[k]), float(a.theta_i_deg[k]),
                         float(a.phi_i_deg[k]), float(a.theta_o_deg[k]), float(a.phi_o_deg[k]),
                         str(points.reason[k]))
            for k in np.flatnonzero(points.reason != "")]


def _manifest(path: Path, data: AltaData, points: RigPoints, sample_id: str | None, now: str) -> dict:
    sample_name = data.header.get("SAMPLE", "").strip('"')
    return {
        "campaign": {"name": f"import of {path.name}", "file": None, "sha256": None, "content": None},
        "sample": {"id": sample_id or sample_name or path.stem, "description": sample_name},
        "rig": {"name": "external", "simulated": False, "config": None},
        "software": {"name": "rig", "version": __version__},
        "counts": {},
        "provenance": {
            "kind": "import", "format": "ALTA text", "imported_utc": now,
            "source_file": str(path.resolve()), "source_sha256": sha256_file(path),
            "header": data.header, "comments": data.comments,
            "dim": [data.n_in, data.n_out], "param_in": data.param_in,
            "param_out": data.param_out, "param_out_used": points.param_out, "vs": data.vs,
            "rows_in_file": len(data), "conversion": points.notes,
            "skip_reasons": CONVERSION_SKIP_REASONS, "conventions": CONVENTIONS,
        },
    }


def import_alta(path: str | Path, out_dir: str | Path, *, sample_id: str | None = None,
                assume_param_out: str = MISSING_PARAM_OUT_DEFAULT) -> Path:
    """Write the ALTA file `path` as a new dataset folder `out_dir`; returns the folder."""
    path = Path(path)
    data = read_alta(path)
    points = to_rig(data, assume_param_out=assume_param_out)
    series = series_index(points.angles.theta_i_deg, points.angles.phi_i_deg)
    ids = [f"{s:02d}-L{line}" for s, line in zip(series, data.line)]
    now = utc_now()
    out = Path(out_dir)
    require_new_output(out, hint="choose another --out")
    with removed_on_failure(out):        # a failed import leaves no half-written folder behind
        writer = DatasetWriter(out, _manifest(path, data, points, sample_id, now))
        try:
            skipped = _skipped(points, ids, series)
            writer.write_skipped(skipped)
            for row in _rows(points, ids, series, now):
                writer.append_row(row)
            writer.event(events.IMPORTED, source_file=str(path.resolve()), rows_in_file=len(data),
                         measured=writer.n_rows, skipped=len(skipped))
            writer.update_manifest(status="complete", counts={"planned": len(data), "measured": writer.n_rows,
                                                              "skipped": len(skipped)})
        finally:
            writer.close()
    return writer.dir
