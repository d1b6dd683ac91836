"""A tabular BSDF for Zemax OpticStudio and LightTools (`rig export --format zemax`; docs/zemax.md).

Format: Radiant Imaging / Zemax, "BSDF Data Interchange File Format Specification" (R. Rykowski, 2008; now
Zemax knowledge-base article 1500005486801, "Zemax Tabular BSDF data file format"). A text file: `#` comment
lines; `Source Measured` (the only value the spec allows), `Symmetry PlaneSymmetrical` (an isotropic sample:
the data are symmetric about the plane of incidence, so azimuths cover 0–180°), `SpectralContent Monochrome`,
`ScatterType BRDF`, then `SampleRotation`, `AngleOfIncidence`, `ScatterAzimuth` and `ScatterRadial`, each a count
and its list (degrees); an empty line, `Monochrome`, `DataBegin`, for each rotation and incidence a `TIS` line
and the BSDF table (one row per azimuth, one column per radial angle, sr⁻¹), `DataEnd`.

Angles (the spec's Figure 1): the scatter angles are measured about the direction of specular reflection.
Radial 0° is the specular direction, the radial angle the angle between it and the outgoing direction; azimuth
0° points from the specular direction toward the sample's normal, increasing counter-clockwise. So with the
light at θi, the normal lies at (azimuth 0°, radial θi), the retroreflection direction at (0°, 2θi), the horizon
at radial 90° + θi (azimuth 0°) and 90° − θi (azimuth 180°); the table holds 0 beyond the horizon.

`TIS` is written as the directional albedo ∫ f cos θo dωo of the table itself (trapezoidal rule over its grid,
both halves of the plane-symmetric hemisphere), so that a reader's integral of the table and the TIS agree.

Grids: a reader interpolates between incidence rows at fixed scatter angles, so a lobe that moves in them must
move less than a fraction of its width between rows. The specular lobe stays at radial 0°; the retroreflective
one sits at radial 2θi and moves twice as fast as θi. The grids therefore follow the lobes' widths, measured on
the source in the plane of incidence (full width at half maximum of a peak inside a ±15° window; a value rising
to the horizon is no lobe): incidence step = retro width / 7 (0.5° to 5°), radial step = specular width / 4 up
to 10° (0.1° to 0.5°) and retro width / 4 beyond (0.25° to 1°); azimuths every 1° within 10° of the plane of
incidence, where both lobes lie, every 2° elsewhere. Steps are rounded down to plain numbers.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike

from rig import __version__
from rig.data.output_folder import new_file
from rig.physics.brdf_models import get_model
from rig.physics.geometry import sph_to_vec

SPEC = ("Zemax knowledge-base article 1500005486801, \"Zemax Tabular BSDF data file format\" "
        "(formerly \"BSDF Data Interchange File Format Specification\", R. Rykowski, Radiant Imaging, 2008)")
AZIMUTH_DEG = np.unique(np.concatenate([np.arange(0.0, 10.0), np.arange(10.0, 170.0, 2.0), np.arange(170.0, 181.0)]))
#: Bounds of the steps chosen from the lobes' widths (degrees).
INCIDENCE_STEP = (0.5, 5.0)
FINE_RADIAL_STEP = (0.1, 0.5)
COARSE_RADIAL_STEP = (0.25, 1.0)
#: Radial angles up to this one get the fine (specular) step.
FINE_RADIAL_MAX_DEG = 10.0
#: Incidences at which the lobes' widths are measured, and the half-window (degrees) searched around each lobe.
WIDTH_PROBES_DEG = (10.0, 30.0, 50.0, 70.0, 85.0)
WIDTH_WINDOW_DEG = 15.0
#: A peak less than this share above its window's minimum is no lobe (the width is then unbounded).
MIN_LOBE_CONTRAST = 0.1


@dataclass(frozen=True)
class ZemaxGrid:
    incidence_deg: np.ndarray
    azimuth_deg: np.ndarray
    radial_deg: np.ndarray
    retro_width_deg: float          # measured full widths at half maximum (inf: no lobe found)
    specular_width_deg: float


class Values(Protocol):
    """What the table needs of a prediction (rig.analysis.prediction.Prediction has it)."""

    @property
    def brdf_per_sr(self) -> np.ndarray: ...

    @property
    def extrapolated(self) -> np.ndarray: ...


class Predictor(Protocol):
    """The part of rig.analysis.prediction.Predictor used here (rig.data sits below rig.analysis)."""

    def predict(self, theta_i_deg: ArrayLike, phi_i_deg: ArrayLike, theta_o_deg: ArrayLike,
                phi_o_deg: ArrayLike) -> Values: ...


@dataclass(frozen=True)
class TableValues:
    """Values: what a predictor that serves the table only returns (no uncertainty: the table holds none)."""

    brdf_per_sr: np.ndarray
    extrapolated: np.ndarray


class FormulaPredictor:
    """A fitted model's values only: the table needs no uncertainty (rig.analysis.predict.ModelPredictor's
    covariance gradients would cost five times the evaluations) and no dataset. Everything is flagged as beyond
    the measured domain: no measurement is consulted."""

    def __init__(self, model: str, params: dict[str, float]):
        self.model, self.params = get_model(model), dict(params)

    def predict(self, theta_i_deg: ArrayLike, phi_i_deg: ArrayLike, theta_o_deg: ArrayLike,
                phi_o_deg: ArrayLike) -> TableValues:
        ti, pi_, to, po = np.broadcast_arrays(*(np.radians(np.asarray(a, float))
                                                for a in (theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg)))
        with np.errstate(all="ignore"):
            f = self.model(sph_to_vec(ti, pi_), sph_to_vec(to, po), self.params)
        return TableValues(f, np.ones(f.shape, bool))


def _in_plane(predictor: Predictor, theta_i: float, x_deg: np.ndarray) -> np.ndarray:
    """f along the plane of incidence at signed angles x from the normal (x = θi: retro; x = −θi: mirror)."""
    theta_o, phi_o = np.abs(x_deg), np.where(x_deg >= 0.0, 0.0, 180.0)
    return np.asarray(predictor.predict(theta_i, 0.0, theta_o, phi_o).brdf_per_sr, float)


def lobe_width_deg(predictor: Predictor, theta_i: float, centre_deg: float) -> float:
    """Full width at half maximum (degrees) of the highest peak within ±15° of `centre_deg` in the plane of
    incidence, over the window's minimum; inf when there is no peak inside the window."""
    x = np.arange(centre_deg - WIDTH_WINDOW_DEG, centre_deg + WIDTH_WINDOW_DEG + 1e-9, 0.05)
    x = x[np.abs(x) < 89.5]
    with np.errstate(all="ignore"):
        f = np.nan_to_num(_in_plane(predictor, theta_i, x), nan=0.0, posinf=0.0, neginf=0.0)
    peak = int(np.argmax(f))
    base, top = float(f.min()), float(f[peak])
    if top <= 0.0 or top - base < MIN_LOBE_CONTRAST * top or peak in (0, len(x) - 1):
        return math.inf                         # flat, or rising toward the window's edge (the horizon): no lobe
    above = f >= base + 0.5 * (top - base)
    lo, hi = peak, peak
    while lo > 0 and above[lo - 1]:
        lo -= 1
    while hi < len(x) - 1 and above[hi + 1]:
        hi += 1
    return float(x[hi] - x[lo]) + 0.05


#: Incidence rows per retroreflective width: the peak, read halfway between two rows, sits one row step from
#: either row's peak, which for a Gaussian-like lobe reads it 1 − exp(−4 ln 2 / 7²) ≈ 5.5 % low.
ROWS_PER_RETRO_WIDTH = 7.0
#: Steps are rounded down to one of these (degrees), so that the lists read as plain numbers.
NICE_STEPS = (0.1, 0.2, 0.25, 0.5, 1.0, 2.0, 2.5, 5.0)


def _steps(lo: float, hi: float, step: float, bounds: tuple[float, float]) -> np.ndarray:
    """lo, lo + h, … up to hi (hi included), h the largest of NICE_STEPS within bounds and not above `step`."""
    allowed = [h for h in NICE_STEPS if bounds[0] <= h <= bounds[1]]
    h = max([a for a in allowed if a <= step] or allowed[:1])
    values = np.arange(round((hi - lo) / h + 0.5)) * h + lo
    return np.round(np.append(values[values < hi - 1e-6], hi), 6)


def grid_for(predictor: Predictor, theta_max_deg: float) -> ZemaxGrid:
    """Incidence rows and scatter angles dense enough for the lobes of `predictor` (module docstring)."""
    probes = [t for t in WIDTH_PROBES_DEG if t <= theta_max_deg] or [theta_max_deg]
    retro = min(lobe_width_deg(predictor, t, t) for t in probes)
    specular = min(lobe_width_deg(predictor, t, -t) for t in probes)
    fine = _steps(0.0, FINE_RADIAL_MAX_DEG, specular / 4, FINE_RADIAL_STEP)
    coarse = _steps(FINE_RADIAL_MAX_DEG, 180.0, retro / 4, COARSE_RADIAL_STEP)
    return ZemaxGrid(incidence_deg=_steps(0.0, theta_max_deg, retro / ROWS_PER_RETRO_WIDTH, INCIDENCE_STEP),
                     azimuth_deg=AZIMUTH_DEG, radial_deg=np.concatenate([fine, coarse[1:]]),
                     retro_width_deg=retro, specular_width_deg=specular)


def scatter_directions(theta_i_deg: float, azimuth_deg: np.ndarray, radial_deg: np.ndarray) -> np.ndarray:
    """Unit outgoing directions (azimuth rows, radial columns, 3) for light at θi in the plane φi = 0 (SCS:
    z the normal, both directions away from the surface)."""
    t = math.radians(theta_i_deg)
    s = np.array([-math.sin(t), 0.0, math.cos(t)])              # the mirror of ωi = (sin θi, 0, cos θi)
    toward_normal = np.array([math.cos(t), 0.0, math.sin(t)])   # n − (n·s)s normalised; (1, 0, 0) at θi = 0
    side = np.cross(s, toward_normal)
    psi, rho = np.radians(azimuth_deg)[:, None, None], np.radians(radial_deg)[None, :, None]
    return np.cos(rho) * s + np.sin(rho) * (np.cos(psi) * toward_normal + np.sin(psi) * side)


def table(predictor: Predictor, theta_i_deg: float, grid: ZemaxGrid) -> tuple[np.ndarray, np.ndarray]:
    """The BSDF table at one incidence (0 below the horizon and where the predictor gives no finite value ≥ 0)
    and the mask of its cells above the horizon that the predictor flagged as extrapolated."""
    wo = scatter_directions(theta_i_deg, grid.azimuth_deg, grid.radial_deg)
    above = wo[..., 2] > 1e-9                   # about half the cells: only these are asked of the predictor
    theta_o = np.degrees(np.arccos(np.clip(wo[above, 2], -1.0, 1.0)))
    phi_o = np.degrees(np.arctan2(wo[above, 1], wo[above, 0]))
    f, extrapolated = np.zeros(above.shape), np.zeros(above.shape, bool)
    with np.errstate(all="ignore"):
        p = predictor.predict(theta_i_deg, 0.0, theta_o, phi_o)
        f[above] = np.nan_to_num(np.asarray(p.brdf_per_sr, float), nan=0.0, posinf=0.0)
    extrapolated[above] = np.asarray(p.extrapolated, bool)
    return np.maximum(f, 0.0), extrapolated


def table_albedo(f: np.ndarray, theta_i_deg: float, grid: ZemaxGrid) -> float:
    """∫ f cos θo dωo of one table: trapezoids in azimuth and radial angle (dω = sin ρ dρ dψ), both halves."""
    wo = scatter_directions(theta_i_deg, grid.azimuth_deg, grid.radial_deg)
    g = f * np.maximum(wo[..., 2], 0.0) * np.sin(np.radians(grid.radial_deg))[None, :]
    inner = np.trapezoid(g, np.radians(grid.radial_deg), axis=1)
    return float(2.0 * np.trapezoid(inner, np.radians(grid.azimuth_deg)))


def _enumeration(label: str, values: Sequence[float]) -> list[str]:
    return [f"{label}\t{len(values)}", "\t".join(f"{v:g}" for v in values)]


@dataclass(frozen=True)
class ZemaxExport:
    path: Path
    grid: ZemaxGrid
    extrapolated_cells: int         # cells above the horizon the predictor flagged as beyond the measured domain
    cells: int                      # cells above the horizon
    #: Per incidence row, the share of the table's albedo (TIS) carried by extrapolated cells: how much of what a
    #: reader integrates was never measured (1 for a model: no measurement is consulted).
    extrapolated_albedo_share: np.ndarray

    def worst_share(self) -> tuple[float, float]:
        """(θi, share) of the row whose albedo rests most on extrapolated cells."""
        k = int(np.argmax(self.extrapolated_albedo_share))
        return float(self.grid.incidence_deg[k]), float(self.extrapolated_albedo_share[k])


def write_zemax(predictor: Predictor, out: Path, *, theta_max_deg: float, comments: Sequence[str]) -> ZemaxExport:
    """Write the tabular BSDF of `predictor` (isotropic, light in the plane φi = 0) under a temporary name, named
    when complete (never over an existing file). Comments must be ASCII (the file is)."""
    grid = grid_for(predictor, theta_max_deg)
    rows = [(float(t), *table(predictor, float(t), grid)) for t in grid.incidence_deg]
    tis = np.array([table_albedo(f, t, grid) for t, f, _ in rows])
    beyond = np.array([table_albedo(np.where(mask, f, 0.0), t, grid) for t, f, mask in rows])
    share = np.divide(beyond, tis, out=np.zeros_like(tis), where=tis > 0)
    header = [f"# exported by rig {__version__}; format: {SPEC}",
              *(f"# {' '.join(c.split())}" for c in comments),
              f"# grid: incidence step {np.diff(grid.incidence_deg).max(initial=0):g} deg, from the lobes' widths "
              f"(FWHM in the plane of incidence): retroreflective {grid.retro_width_deg:.3g} deg, specular "
              f"{grid.specular_width_deg:.3g} deg",
              f"# share of each TIS from cells beyond the measured domain: {share.min():.0%} to {share.max():.0%}",
              "Source\tMeasured", "Symmetry\tPlaneSymmetrical", "SpectralContent\tMonochrome", "ScatterType\tBRDF",
              *_enumeration("SampleRotation", [0.0]), *_enumeration("AngleOfIncidence", grid.incidence_deg.tolist()),
              *_enumeration("ScatterAzimuth", grid.azimuth_deg.tolist()),
              *_enumeration("ScatterRadial", grid.radial_deg.tolist()), "", "Monochrome", "DataBegin"]
    with new_file(Path(out)) as tmp, tmp.open("w", encoding="ascii", errors="replace", newline="\n") as fh:
        fh.write("\n".join(header) + "\n")
        for (_, f, _), albedo in zip(rows, tis):
            fh.write(f"TIS\t{albedo:.6g}\n")
            row = "\t".join(["%.5g"] * f.shape[1])        # one %-format of the whole table: savetxt's rows cost 10×
            fh.write("\n".join([row] * f.shape[0]) % tuple(f.ravel().tolist()) + "\n")
        fh.write("DataEnd\n")
    return ZemaxExport(Path(out), grid, sum(int(np.count_nonzero(mask)) for _, _, mask in rows),
                       sum(int(np.count_nonzero(scatter_directions(t, grid.azimuth_deg, grid.radial_deg)[..., 2]
                                                > 1e-9)) for t, _, _ in rows), share)
