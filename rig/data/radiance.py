"""Radiance BSDF exports: pab-opto "Mountain" files for `pabopto2bsdf`, and a tensor-tree XML via `bsdf2ttree`.

Conventions (docs/radiance.md; pabopto2bsdf(1), bsdf2ttree(1), G. Ward, LBNL-ETA/Radiance): Radiance's
BSDF frame has θ = 0 along the front normal, φ counter-clockwise seen from the front, φ = 90° "up",
and both vectors pointing away from the surface, the incident one toward the source. With
`#upphi 90` pabopto2bsdf applies no rotation, so that frame is rig's SCS and angles go in unchanged.

pabopto2bsdf infers the sample's symmetry from the incident azimuths (src/cv/bsdfrep.c,
`new_input_direction`): all φi within 1° of one in-plane azimuth → isotropic; φi in one quadrant
only → quadrilateral (the data are mirrored into the other three), and so on. A campaign whose
φi ≠ 0 series exist only near grazing (the paper's φi = 23°, 45° at θi ≥ 70°) is therefore read as
quadrilateral and interpolated badly at low θi. For an isotropic sample every series is turned to
φi = 0 (each point's φo − φi: a rotation about the normal, a symmetry of an isotropic BRDF) and
series of the same θi are merged, so pabopto2bsdf sees one file per incidence, all in one plane.

Sparse incidences: between incidences pabopto2bsdf interpolates by displacement ("transport plan")
between the radial-basis fits of neighbouring files (Ward, Kurt & Bonneel, EG MAM 2014). It needs
at least two files, and it cannot follow the retro and specular lobes, which move with θi, across
incidences farther apart than about a lobe width; this module warns (`SparseIncidenceWarning`,
through `warnings.warn`, so callers and the CLI choose to print or raise) when fewer than two
incidences are left, when consecutive θi (or normal incidence and the lowest θi) are more than
`MAX_THETA_GAP_DEG` apart, or, for an anisotropic export, when the φi coverage makes
pabopto2bsdf assume a symmetry (it mirrors the data rather than interpolating them).
"""

from __future__ import annotations

import importlib
import os
import signal
import subprocess
import sys
import tempfile
import warnings
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any, Literal

import numpy as np
from numpy.typing import ArrayLike

from rig import __version__
from rig.core.interrupts import held_signals
from rig.data.dataset_reader import Dataset
from rig.data.output_folder import new_file
from rig.data.radiance_cal import FUNCTION, model_cal
from rig.physics.geometry import mean_direction_deg, wrap_360

#: Series whose mean θi differ by at most this (degrees) are one incidence once turned to φi = 0
#: (achieved angles scatter by ~0.01° around a requested one).
THETA_MERGE_TOL_DEG = 0.5
#: Consecutive incidences farther apart than this (degrees) are too sparse for pabopto2bsdf: about
#: the width of a road marking's lobes (RetroPhong n = 24: cos^n falls to 1/e at 1/√n rad ≈ 12°).
MAX_THETA_GAP_DEG = 20.0
#: pabopto2bsdf counts an incident azimuth within this (degrees) of a multiple of 90° as in-plane.
IN_PLANE_TOL_DEG = 1.0
#: pabopto2bsdf trusts no azimuth below this incident θ (degrees).
POLE_THETA_DEG = 1.0
#: bsdf2ttree's maximum tree resolution 2^N per dimension (its default, 6) and its culling percentage.
RESOLUTION_LOG2 = 6
PERCENT_CULL = 90.0


class SparseIncidenceWarning(UserWarning):
    """The incidences written are too sparse for pabopto2bsdf to interpolate well (module docstring)."""


class RadianceError(RuntimeError):
    """A Radiance tool is missing or failed; the message says which and why."""


@dataclass(frozen=True)
class MountainFile:
    """One pab-opto file: an incidence and the views measured under it (degrees, f in sr⁻¹)."""

    theta_i_deg: float
    phi_i_deg: float
    theta_o_deg: np.ndarray
    phi_o_deg: np.ndarray
    brdf_per_sr: np.ndarray
    series: tuple[int, ...]


def azimuth_text(phi_deg: float, decimals: int) -> str:
    """φ wrapped to [0, 360) and rounded to `decimals`, then wrapped again: 359.99996 reads 0.0, never 360.0."""
    return f"{float(wrap_360(round(float(wrap_360(phi_deg)), decimals))):.{decimals}f}"


def file_name(series: tuple[int, ...], theta_i_deg: float, phi_i_deg: float) -> str:
    """`seriesSS[-SS…]_tTTT.T_pPPP.P.txt`: the series merged into the file, then its incidence."""
    return f"series{'-'.join(f'{s:02d}' for s in series)}_t{theta_i_deg:05.1f}_p{azimuth_text(phi_i_deg, 1):0>5}.txt"


def relative_azimuth_deg(phi_i_deg: ArrayLike, phi_o_deg: ArrayLike) -> np.ndarray:
    """φo − φi in [0, 360): the view's azimuth once the incidence is turned to φi = 0."""
    return wrap_360(np.asarray(phi_o_deg, float) - np.asarray(phi_i_deg, float))


def series_files(ds: Dataset) -> list[MountainFile]:
    """One file per series, angles as measured (an anisotropic sample)."""
    files = []
    for s in np.unique(ds["series"]).astype(int):
        rows = ds["series"] == s
        theta_i, phi_i = mean_direction_deg(ds["theta_i_deg"][rows], ds["phi_i_deg"][rows])
        files.append(MountainFile(theta_i, phi_i, ds["theta_o_deg"][rows], ds["phi_o_deg"][rows],
                                  ds["brdf_per_sr"][rows], (int(s),)))
    return files


def merged_isotropic_files(ds: Dataset, tol_deg: float = THETA_MERGE_TOL_DEG) -> list[MountainFile]:
    """One file per θi (series within `tol_deg` of the previous one merged), every view turned to φi = 0."""
    series = np.unique(ds["series"]).astype(int)
    theta = np.array([mean_direction_deg(ds["theta_i_deg"][ds["series"] == s],
                                         ds["phi_i_deg"][ds["series"] == s])[0] for s in series])
    order = np.argsort(theta, kind="stable")
    groups: list[list[int]] = []
    for k in order:
        if groups and theta[k] - theta[groups[-1][-1]] <= tol_deg:
            groups[-1].append(int(k))
        else:
            groups.append([int(k)])
    files = []
    for group in groups:
        rows = np.isin(ds["series"], series[group])
        files.append(MountainFile(float(np.mean(ds["theta_i_deg"][rows])), 0.0, ds["theta_o_deg"][rows],
                                  relative_azimuth_deg(ds["phi_i_deg"][rows], ds["phi_o_deg"][rows]),
                                  ds["brdf_per_sr"][rows], tuple(int(s) for s in sorted(series[group]))))
    return files


def quadrant_coverage(phi_i_deg: ArrayLike, theta_i_deg: ArrayLike) -> set[int]:
    """Quadrants (0–3) holding an incident azimuth that is not in-plane, as pabopto2bsdf counts them."""
    phi = wrap_360(np.asarray(phi_i_deg, float))
    off_plane = np.abs(phi - 90.0 * np.round(phi / 90.0)) > IN_PLANE_TOL_DEG
    usable = off_plane & (np.asarray(theta_i_deg, float) >= POLE_THETA_DEG)
    return {int(q) % 4 for q in np.floor(phi[usable] / 90.0)}


def sparsity_problems(files: list[MountainFile], *, isotropic: bool) -> list[str]:
    """Why these files are too sparse for pabopto2bsdf (module docstring); empty when they are not."""
    if len(files) < 2:
        return [f"{len(files)} incidence(s): pabopto2bsdf needs at least two"]
    problems = []
    thetas = np.unique(np.round([f.theta_i_deg for f in files], 6))
    steps = np.diff(np.concatenate([[0.0], thetas]))
    if steps.max() > MAX_THETA_GAP_DEG:
        k = int(np.argmax(steps))
        low = 0.0 if k == 0 else thetas[k - 1]
        problems.append(f"incidences θi = {low:.1f}° and {thetas[k]:.1f}° are {steps[k]:.1f}° apart "
                        f"(more than {MAX_THETA_GAP_DEG:g}°): the lobes cannot be interpolated between them")
    quadrants = quadrant_coverage([f.phi_i_deg for f in files], [f.theta_i_deg for f in files])
    if not isotropic and quadrants and len(quadrants) < 4:
        problems.append(f"incident azimuths cover quadrant(s) {sorted(quadrants)} only: pabopto2bsdf will "
                        "mirror the data into the others; measure all four, or export the sample as isotropic")
    return problems


def _write_mountain(path: Path, f: MountainFile, sample: str, source: Path) -> None:
    lines = [f'#sample_name "{sample}"', f"#data written by rig {__version__} from {source}",
             f"#intheta {f.theta_i_deg:.6f}", f"#inphi {azimuth_text(f.phi_i_deg, 6)}", "#upphi 90",
             f"#datapoints_in_file: {len(f.brdf_per_sr)}", "#format: theta phi BSDF"]
    lines += [f"{t!r} {p!r} {v!r}" for t, p, v in
              zip(f.theta_o_deg.tolist(), f.phi_o_deg.tolist(), f.brdf_per_sr.tolist())]
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")


def export_radiance(ds: Dataset, out: Path, *, isotropic: bool) -> list[Path]:
    """Write pab-opto files for pabopto2bsdf into the folder `out`; returns them in θi order.

    `isotropic`: every series turned to φi = 0 and series of the same θi merged (one file per
    incidence); otherwise one file per series, as measured. Emits a `SparseIncidenceWarning` when
    the incidences are too sparse for pabopto2bsdf (module docstring).
    """
    if len(ds) == 0:
        raise RadianceError(f"{ds.path}: no measured point to export")
    files = merged_isotropic_files(ds) if isotropic else series_files(ds)
    for problem in sparsity_problems(files, isotropic=isotropic):
        warnings.warn(f"{ds.path}: {problem}", SparseIncidenceWarning, stacklevel=2)
    out.mkdir(parents=True, exist_ok=True)
    sample = ds.sample_id()
    paths = []
    for f in files:
        path = out / file_name(f.series, f.theta_i_deg, f.phi_i_deg)
        _write_mountain(path, f, sample, ds.path)
        paths.append(path)
    return paths


def _pyradiance() -> ModuleType:
    try:
        return importlib.import_module("pyradiance")
    except ImportError:
        raise RadianceError("the Radiance exports need pyradiance (it ships pabopto2bsdf and bsdf2ttree): "
                            "pip install 'rig[radiance]' or pip install pyradiance") from None


def run_tool(name: str, args: list[str], stdout: Path, stdin: str | None = None) -> None:
    """Run the Radiance program `name` shipped with pyradiance, `stdin` on its input, its output into `stdout`.

    The program runs in a session of its own and whatever is left of that session is killed when this returns
    or is interrupted (`rig.core.interrupts`): bsdf2ttree runs rttree_reduce children that would otherwise go
    on writing after rig has ended."""
    binpath = Path(_pyradiance().BINPATH)
    env = {**os.environ, "PATH": f"{binpath}{os.pathsep}{os.environ.get('PATH', '')}"}   # bsdf2ttree → rttree_reduce
    proc = None
    with stdout.open("wb") as fh:
        try:
            with held_signals():     # an interrupt during Popen() would lose the handle of a running tool
                proc = subprocess.Popen([str(binpath / name), *args], stdin=subprocess.DEVNULL if stdin is None
                                        else subprocess.PIPE, stdout=fh, stderr=subprocess.PIPE, env=env,
                                        start_new_session=True)
            _, err = proc.communicate(None if stdin is None else stdin.encode())
        finally:
            if proc is not None:
                _end_session(proc)
    if proc.returncode != 0:
        stdout.unlink(missing_ok=True)
        message = err.decode(errors="replace").strip().splitlines()[-3:]
        raise RadianceError(f"{name} {' '.join(args)} failed (exit {proc.returncode}): {' / '.join(message)}")


def _end_session(proc: subprocess.Popen) -> None:
    """Kill the tool's process group (itself if it still runs, and its children), then reap it."""
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:       # the tool and all its children have ended
        pass
    proc.wait()


def _ttree_options(resolution_log2: int, percent_cull: float) -> list[str]:
    # -p alone: no progress bar. Reciprocity averaging stays off (bsdf2ttree's default): RetroPhong is not reciprocal.
    return ["-p", "-g", str(resolution_log2), "-t", f"{percent_cull:g}"]


def export_radiance_xml(ds: Dataset, out: Path, *, source: Literal["model", "data"],
                        fit: Mapping[str, Any] | None = None, isotropic: bool = True,
                        resolution_log2: int = RESOLUTION_LOG2, percent_cull: float = PERCENT_CULL) -> list[Path]:
    """Write a tensor-tree BSDF XML (front reflection) to the file `out`, built by Radiance's bsdf2ttree.

    source "model": from `fit` ({"model": ..., "params": {...}}, what `rig fit --json` writes) through
    a `.cal` of the model (`rig.data.radiance_cal`); `bsdf2ttree -t3`, the models being isotropic.
    source "data": the measured points through `export_radiance(ds, …, isotropic=isotropic)`,
    `pabopto2bsdf`, then `bsdf2ttree`. `resolution_log2` and `percent_cull` are bsdf2ttree's `-g`, `-t`.
    """
    if source == "model" and fit is None:
        raise ValueError("source 'model' needs fit = {'model': ..., 'params': {...}} (rig fit --json)")
    if source not in ("model", "data"):
        raise ValueError(f"source must be 'model' or 'data', not {source!r}")
    with tempfile.TemporaryDirectory(prefix="rig-radiance-") as tmp, new_file(out) as xml:
        work = Path(tmp)
        if fit is not None and source == "model":
            cal = work / "model.cal"
            cal.write_text(model_cal(str(fit["model"]), fit["params"]), encoding="utf-8")
            run_tool("bsdf2ttree", ["-t3", *_ttree_options(resolution_log2, percent_cull), "-f", str(cal), FUNCTION],
                     xml)
        else:
            mountain = export_radiance(ds, work / "mountain", isotropic=isotropic)
            if len(mountain) < 2:
                raise RadianceError(f"{ds.path}: one incidence only; pabopto2bsdf interpolates between incidences "
                                    "and needs at least two: measure another one, or export a fitted model "
                                    "(--source model --fit FIT.json)")
            sir = work / "data.sir"
            run_tool("pabopto2bsdf", [str(p) for p in mountain], sir)
            run_tool("bsdf2ttree", [*_ttree_options(resolution_log2, percent_cull), str(sir)], xml)
    return [out]


#: Evaluates an XML in a child process: pyradiance's `load_file` hands Radiance's cached SDData to Python, which
#: frees it when the object dies while the cache still points to it (a double free, or a stale entry for a file
#: written again under the same name). The child reads "θi φi θo φo" lines and never runs that clean-up.
_QUERY_CHILD = """
import os, sys
from pyradiance import bsdf
sd = bsdf.load_file(sys.argv[1])
rows = [[float(v) for v in line.split()] for line in sys.stdin if line.strip()]
sys.stdout.write("".join(f"{float(bsdf.query(sd, *r)[1])!r}\\n" for r in rows))
sys.stdout.flush()
os._exit(0)
"""


def evaluate_xml(xml: Path, theta_i_deg: ArrayLike, phi_i_deg: ArrayLike, theta_o_deg: ArrayLike,
                 phi_o_deg: ArrayLike) -> np.ndarray:
    """BSDF (CIE Y, sr⁻¹) of a Radiance XML at (ωi, ωo) given in degrees, rig's SCS (= Radiance's frame).

    Radiance's SDevalBSDF(inVec, outVec): inVec toward the source, both away from the surface, as ωi, ωo.
    """
    _pyradiance()
    angles = np.broadcast_arrays(*(np.asarray(a, float) for a in (theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg)))
    query = "".join(f"{a!r} {b!r} {c!r} {d!r}\n" for a, b, c, d in zip(*(x.ravel().tolist() for x in angles)))
    done = subprocess.run([sys.executable, "-c", _QUERY_CHILD, str(xml)], input=query.encode(), capture_output=True,
                          check=False)
    if done.returncode != 0:
        raise RadianceError(f"cannot evaluate {xml}: {done.stderr.decode(errors='replace').strip()[-300:]}")
    return np.array([float(v) for v in done.stdout.split()]).reshape(angles[0].shape)
