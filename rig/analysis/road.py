"""Road-lighting quantities at their standard geometries, from a BRDF predictor (definitions: docs/road-lighting.md).

The per-point `rl` export (rig.data.export) gives L/E at the geometries the rig measured; the
standards ask for fixed geometries the rig cannot reach, so these come from a predictor (a fitted
model or an interpolant, rig.analysis.prediction) evaluated there:

- R_L (EN 1436 "30 m": headlamp 0.65 m, eye 1.2 m, 30 m away; ASTM E1710-18 §1.2, §5.5):
  R_L = L/E⊥ = f_r(θi 88.76°, θo 87.71°, Δφ 0°) · cos θi, E⊥ on a plane across the beam (CIE ILV 17-24-104);
- Qd (CIE ILV term 713; observation 2.29°, ASTM E2302 §1.2): uniform sky, E on the marking, so
  Qd = (1/π) ∫_H f_r(ωi, ωo) cos θi dωi at θo = 87.71°;
- the r-table (CIE 144, IES): r(β, tan γ) = f_r(θi = γ, θo = 89°, Δφ = 180° − β) · cos³γ on the standard
  20 β × 29 tan γ grid, tabulated × 10⁴; Δφ = φi − φo, Δφ = 0 the observer's side (β = 180°, luminaire
  behind the observer), Δφ = 180° the far side (β = 0°);
- Q0 = (1/Ω0) ∫_Ω0 q dω (van Bommel, Road Lighting, Springer 2015, ch. 12), q = f_r at θo = 89°,
  Ω0 = every incidence with tan γ ≤ 12 on both sides of the observation plane (the table's range);
  S1 = r(0°, 2) / r(0°, 0); the CIE R, C and N classes by S1 (van Bommel Table 12.2).

Integrals (Qd, Q0): n-point Gauss–Legendre in cos θi times a 2n-point periodic rule in the
azimuth from φo, warped (φ = u − (β/2) sin 2u, β = 0.95) so that nodes are 39× denser in the plane
of observation, where the retroreflection and specular lobes lie. Exact for a Lambertian; for
Spieringhs et al. 2023's RM1 RetroPhong fit n = 48 and 96 agree to rounding and match a fine midpoint
rule to 1e-6 relative (tests/analysis/test_road.py). Narrower lobes (an interpolant of a glossy
sample) may need a larger n: compare two.

Uncertainties (k = 1): a quantity Y computed from predicted values f_k is given
u(Y) = Σ_k |∂Y/∂f_k| u(f_k), the largest standard uncertainty any correlation between the f_k can
give (the triangle inequality on the covariance). The predictor's values are correlated (a fitted
model's come from one parameter covariance) and their correlation is not part of the predictor's
interface, so this bound is the honest choice: for the positively weighted sums R_L, Qd, Q0 and each
r-table cell it is full positive correlation; for the ratio S1 it is correlation −1 (the relative
uncertainties add). The quadrature error is not included (it is orders of magnitude smaller).

The calibrations shared by every point (the camera's coefficient and the meter head's factor,
rig.physics.budget) are not in the predictor's u when it comes from a fit weighted by the point-to-point
part: they shift every value by one common relative error, so R_L, Qd, Q0 and every r-table cell by that
same relative amount (S1, a ratio, not at all). That part is given apart (`u_correlated` in road.json),
from the dataset's `shared_calibration_u_rel`.

Extrapolation: the rig measures θi ≤ 85° and cannot view within the lamp's occlusion cone (the camera
cannot be where the lamp is), so R_L (θi 88.76°, 1.05° from retroreflection), the r-table rows with
tan γ > tan 85° = 11.4 and the near-retro cells come from the predictor's extrapolation; which ones
is read from the predictor's `extrapolated` flags and said in plain words by `extrapolation_note`.
"""

from __future__ import annotations

import json
import math
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from rig import __version__
from rig.analysis.prediction import Predictor
from rig.data.output_folder import new_file

#: EN 1436 "30 m" geometry (ASTM E1710-18 §1.2): entrance 88.76°, observation elevation 2.29°; same azimuth.
R_L_THETA_I_DEG = 88.76
R_L_THETA_O_DEG = 87.71
#: Qd viewing: 2.29° above the surface (30 m, eye 1.2 m; ASTM E2302 §1.2).
QD_THETA_O_DEG = 87.71
#: r-table observer: 1° above the surface by convention (CIE ILV 17-21-103).
R_TABLE_THETA_O_DEG = 89.0
#: The standard r-table grid (CIE 144 / IES r-tables): 20 β (degrees) × 29 tan γ.
BETA_DEG = np.array([0, 2, 5, 10, 15, 20, 25, 30, 35, 40, 45, 60, 75, 90, 105, 120, 135, 150, 165, 180], float)
TAN_GAMMA = np.concatenate([np.linspace(0.0, 2.0, 9), np.linspace(2.5, 12.0, 20)])
#: Row of r(0°, tan γ = 2), S1's numerator.
_S1_ROW = int(np.flatnonzero(np.isclose(TAN_GAMMA, 2.0))[0])
#: r-tables list r × 10⁴.
R_TABLE_SCALE = 1e4
#: Q0's solid angle Ω0: the incidences of the table, tan γ ≤ 12, over the whole azimuth (both sides).
Q0_TAN_GAMMA_MAX = 12.0
#: sr⁻¹ (≡ cd·m⁻²·lx⁻¹) → mcd·m⁻²·lx⁻¹.
MCD = 1e3
#: Azimuth warp of the integrals: node density (1 + β)/(1 − β) higher in the plane of observation.
_AZIMUTH_CLUSTERING = 0.95
#: Classes as lower limits, each class holding from its limit up to the next one's.
#: CIE road surfaces by S1 (van Bommel 2015 Table 12.2), with their standard Q0 in `STANDARD_Q0`.
S1_CLASSES: dict[str, dict[str, float]] = {
    "R": {"R1": 0.0, "R2": 0.42, "R3": 0.85, "R4": 1.35},
    "C": {"C1": 0.0, "C2": 0.40},
    "N": {"N1": 0.0, "N2": 0.28, "N3": 0.60, "N4": 1.30},
}
STANDARD_Q0 = {"R1": 0.10, "R2": 0.07, "R3": 0.07, "R4": 0.08, "C1": 0.10, "C2": 0.07,
               "N1": 0.10, "N2": 0.07, "N3": 0.07, "N4": 0.08}
#: EN 1436 dry road markings, mcd·m⁻²·lx⁻¹, as quoted by the Walloon spec RW99 L.4.3.2.1–2.
R_L_CLASSES = {"R0": 0.0, "R1": 80.0, "R2": 100.0, "R3": 150.0, "R4": 200.0, "R5": 300.0}
QD_CLASSES = {"Q0": 0.0, "Q1": 80.0, "Q2": 100.0, "Q3": 130.0, "Q4": 160.0}
#: Coverage factor of the class ranges reported next to each class.
CLASS_K = 2.0


@dataclass(frozen=True)
class Integral:
    """A solid-angle integral of predicted values: value, u (k = 1), share of the value from extrapolated nodes."""

    value: float
    u: float
    extrapolated_share: float


@dataclass(frozen=True)
class RoadQuantities:
    """Road-lighting quantities of one sample at the standard geometries (units in the names; k = 1).

    r-table arrays are (29 tan γ rows, 20 β columns) on `BETA_DEG` × `TAN_GAMMA`.
    """

    method: str
    phi_o_deg: float
    R_L_mcd_m2_lx: float
    u_R_L_mcd_m2_lx: float
    R_L_extrapolated: bool
    Qd: Integral                      # mcd·m⁻²·lx⁻¹
    r_x1e4: np.ndarray
    u_r_x1e4: np.ndarray
    r_extrapolated: np.ndarray
    Q0: Integral                      # sr⁻¹ (≡ cd·m⁻²·lx⁻¹)
    S1: float
    u_S1: float
    #: Relative standard uncertainty shared by every value (calibrations), apart from the u above.
    u_rel_correlated: float = 0.0


def cap_quadrature(theta_max_deg: float, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Nodes (θ, φ in degrees) and weights (sr) with Σ w g(θ, φ) ≈ ∫ g dω over the cap θ ≤ θmax.

    φ is measured from the plane in which the lobes lie (the nodes cluster at φ = 0° and 180°);
    see the module docstring. Arrays of shape (n, 2n); Σ w = 2π(1 − cos θmax) to rounding.
    """
    x, w = np.polynomial.legendre.leggauss(n)
    mu_min = np.cos(np.radians(theta_max_deg))
    mu, w_mu = mu_min + 0.5 * (1.0 - mu_min) * (x + 1.0), 0.5 * (1.0 - mu_min) * w
    u = (np.arange(2 * n) + 0.5) * (np.pi / n)
    phi = u - 0.5 * _AZIMUTH_CLUSTERING * np.sin(2.0 * u)
    w_phi = (1.0 - _AZIMUTH_CLUSTERING * np.cos(2.0 * u)) * (np.pi / n)
    theta_deg, phi_deg = np.broadcast_arrays(np.degrees(np.arccos(mu))[:, None], np.degrees(phi)[None, :])
    return theta_deg, phi_deg, w_mu[:, None] * w_phi[None, :]


def incidence_integral(predictor: Predictor, theta_o_deg: float, phi_o_deg: float, theta_max_deg: float, *,
                       cosine: bool, scale: float, n: int) -> Integral:
    """scale · ∫ f_r(ωi, ωo) [cos θi] dωi over the incidences θi ≤ θmax, at the view (θo, φo).

    cosine: weigh by cos θi (an illuminance on the surface, as in Qd).
    """
    theta_i, dphi, w = cap_quadrature(theta_max_deg, n)
    if cosine:
        w = w * np.cos(np.radians(theta_i))
    p = predictor.predict(theta_i, phi_o_deg + dphi, theta_o_deg, phi_o_deg)
    value = float(np.sum(w * p.brdf_per_sr))
    part = float(np.sum(w * p.brdf_per_sr * p.extrapolated))
    return Integral(value=float(scale * value), u=float(abs(scale) * np.sum(w * p.u_brdf_per_sr)),
                    extrapolated_share=part / value if value else 0.0)


def r_table_angles_deg(phi_o_deg: float = 0.0) -> tuple[np.ndarray, np.ndarray, float, float]:
    """(θi, φi, θo, φo) of the r-table cells, degrees; θi and φi of shape (29, 20)."""
    theta_i, beta = np.meshgrid(np.degrees(np.arctan(TAN_GAMMA)), BETA_DEG, indexing="ij")
    return theta_i, phi_o_deg + 180.0 - beta, R_TABLE_THETA_O_DEG, phi_o_deg


def classify(value: float, limits: Mapping[str, float]) -> str | None:
    """The class whose lower limit is the highest one ≤ value (limits listed in increasing order); None for a
    value that is not a number (a quantity the predictor leaves undefined)."""
    if math.isnan(value):
        return None
    passed = [name for name, lower in limits.items() if value >= lower]
    return passed[-1] if passed else next(iter(limits))


def classes_within(value: float, u: float, limits: Mapping[str, float], k: float = CLASS_K) -> list[str]:
    """Every class that value ± k·u reaches, in order: all of them when u is unknown or infinite, none when the
    value is not finite."""
    names = list(limits)
    if not math.isfinite(value):
        return []
    if not math.isfinite(u):
        return names
    lo, hi = (names.index(classify(value + sign * k * u, limits) or names[0]) for sign in (-1, 1))
    return names[lo:hi + 1]


def shared_calibration_u_rel(dataset: Any) -> float:
    """The relative u every point of a dataset shares: its camera and meter calibrations and the static grain's
    common part (median over rows of u_rel_calibration ⊕ u_rel_meter_calibration ⊕ u_rel_texture_static, the
    last 0 where not given; 0 for a dataset without the calibrations, e.g. an import)."""
    cols = [dataset[c] for c in ("u_rel_calibration", "u_rel_meter_calibration") if c in dataset.columns]
    if len(cols) != 2 or not len(cols[0]):
        return 0.0
    static = np.nan_to_num(dataset["u_rel_texture_static"]) if "u_rel_texture_static" in dataset.columns else 0.0
    return float(np.nanmedian(np.sqrt(cols[0] ** 2 + cols[1] ** 2 + static ** 2)))


def road_quantities(predictor: Predictor, *, phi_o_deg: float = 0.0, n: int = 96,
                    correlated_u_rel: float = 0.0) -> RoadQuantities:
    """R_L, Qd, the r-table, Q0 and S1 of the sample `predictor` describes (see the module docstring).

    phi_o_deg: the observer's azimuth in the sample's frame (the traffic direction); matters only for
    anisotropic samples. n: Gauss–Legendre order of the two integrals (2n² predictions each).
    correlated_u_rel: the calibrations' relative u shared by every value (`shared_calibration_u_rel`).
    """
    with np.errstate(all="ignore"):      # degenerate predictions (0/0, overflow) become null in road.json
        q = _road_quantities(predictor, phi_o_deg, n)
    return replace(q, u_rel_correlated=correlated_u_rel)


def _road_quantities(predictor: Predictor, phi_o_deg: float, n: int) -> RoadQuantities:
    rl = predictor.predict(R_L_THETA_I_DEG, phi_o_deg, R_L_THETA_O_DEG, phi_o_deg)
    cos_rl = np.cos(np.radians(R_L_THETA_I_DEG))
    qd = incidence_integral(predictor, QD_THETA_O_DEG, phi_o_deg, 90.0, cosine=True, scale=MCD / np.pi, n=n)
    gamma_max_deg = float(np.degrees(np.arctan(Q0_TAN_GAMMA_MAX)))
    omega0_sr = 2.0 * np.pi * (1.0 - np.cos(np.radians(gamma_max_deg)))
    q0 = incidence_integral(predictor, R_TABLE_THETA_O_DEG, phi_o_deg, gamma_max_deg, cosine=False,
                            scale=1.0 / omega0_sr, n=n)
    theta_i, phi_i, theta_o, phi_o = r_table_angles_deg(phi_o_deg)
    table = predictor.predict(theta_i, phi_i, theta_o, phi_o)
    cos3 = R_TABLE_SCALE * np.cos(np.radians(theta_i)) ** 3
    r, u_r = table.brdf_per_sr * cos3, table.u_brdf_per_sr * cos3
    s1 = float(r[_S1_ROW, 0] / r[0, 0])
    return RoadQuantities(
        method=predictor.method, phi_o_deg=phi_o_deg,
        R_L_mcd_m2_lx=float(MCD * rl.brdf_per_sr * cos_rl), u_R_L_mcd_m2_lx=float(MCD * rl.u_brdf_per_sr * cos_rl),
        R_L_extrapolated=bool(rl.extrapolated), Qd=qd,
        r_x1e4=r, u_r_x1e4=u_r, r_extrapolated=np.asarray(table.extrapolated, bool),
        Q0=q0, S1=s1, u_S1=float(abs(s1) * (u_r[_S1_ROW, 0] / r[_S1_ROW, 0] + u_r[0, 0] / r[0, 0])))


def _grouped(labels: Sequence[str], keys: Sequence[str]) -> list[tuple[str, str]]:
    """Runs of equal consecutive keys, each as (key, "first label–last label"); runs of "" left out."""
    runs: list[tuple[str, str]] = []
    start = 0
    for i in range(1, len(keys) + 1):
        if i == len(keys) or keys[i] != keys[start]:
            if keys[start]:
                span = labels[start] if i - 1 == start else f"{labels[start]}–{labels[i - 1]}"
                runs.append((keys[start], span))
            start = i
    return runs


def _number(x: float) -> str:
    return f"{x:g}"


def r_table_note(extrapolated: np.ndarray) -> str:
    """Which r-table cells are extrapolated, as ranges of tan γ and β (e.g. "tan γ 11.5–12 at every β")."""
    betas = [_number(b) for b in BETA_DEG]
    row_keys = []
    for row in extrapolated:
        spans = [span for _, span in _grouped(betas, ["x" if e else "" for e in row])]
        row_keys.append("every β" if row.all() else ("β " + ", ".join(spans) if spans else ""))
    parts = [f"tan γ {span} at {key}" for key, span in _grouped([_number(t) for t in TAN_GAMMA], row_keys)]
    return f"{int(extrapolated.sum())} of {extrapolated.size} cells extrapolated" + (": " + "; ".join(parts)
                                                                                      if parts else "")


def extrapolation_note(q: RoadQuantities) -> str:
    """Where the quantities rest on the predictor's extrapolation, in plain words."""
    def share(name: str, integral: Integral) -> str:
        return f"{name}: {100 * integral.extrapolated_share:.1f} % of the integral from extrapolated incidences."

    s1_cells = q.r_extrapolated[[0, _S1_ROW], 0]
    return " ".join([
        f"R_L (θi {R_L_THETA_I_DEG}°, θo {R_L_THETA_O_DEG}°, same azimuth): "
        + ("extrapolated." if q.R_L_extrapolated else "within the measured domain."),
        share("Qd", q.Qd), share("Q0", q.Q0),
        f"r-table (θo {R_TABLE_THETA_O_DEG:g}°): {r_table_note(q.r_extrapolated)}.",
        "S1: " + ("its cells r(0°, 0) and r(0°, 2) are within the measured domain." if not s1_cells.any()
                  else "from extrapolated cells."),
    ])


def road_json(q: RoadQuantities) -> dict:
    """The content of road.json: the keys of the issue first, then classes, uncertainties and geometry.

    JSON has no NaN or infinity: a quantity the predictor leaves undefined (0/0 on an all-zero sample, an
    overflow at 1e300, an undetermined parameter's infinite u) is written as null, and `undefined` lists them."""
    document = _road_document(q)
    undefined: list[str] = []
    document = _nulls(document, "", undefined)
    if undefined:
        document["undefined"] = {"quantities": list(dict.fromkeys(undefined)), "note": UNDEFINED_NOTE}
    return document


#: road.json's word on the quantities written as null.
UNDEFINED_NOTE = ("not finite (division by zero, overflow or an undetermined model parameter), written as null; "
                  "classes that depend on them are null")


def _nulls(value: Any, key: str, undefined: list[str]) -> Any:
    """`value` with every float that is not finite replaced by None; the dotted keys of those in `undefined`."""
    if isinstance(value, float) and not math.isfinite(value):
        undefined.append(key)
        return None
    if isinstance(value, dict):
        return {k: _nulls(v, f"{key}.{k}" if key else k, undefined) for k, v in value.items()}
    if isinstance(value, list):
        return [_nulls(v, key, undefined) for v in value]
    return value


def _road_document(q: RoadQuantities) -> dict:
    s1_classes = {family: classify(q.S1, limits) for family, limits in S1_CLASSES.items()}
    return {
        "R_L_mcd_m2_lx": q.R_L_mcd_m2_lx, "u_R_L_mcd_m2_lx": q.u_R_L_mcd_m2_lx,
        "Qd_mcd_m2_lx": q.Qd.value, "u_Qd_mcd_m2_lx": q.Qd.u,
        "r_table": {"beta_deg": BETA_DEG.tolist(), "tan_gamma": TAN_GAMMA.tolist(), "r_x1e4": q.r_x1e4.tolist(),
                    "u_r_x1e4": q.u_r_x1e4.tolist(), "extrapolated": q.r_extrapolated.tolist()},
        "Q0": q.Q0.value, "S1": q.S1,
        "extrapolated": extrapolation_note(q),
        "u_Q0": q.Q0.u, "u_S1": q.u_S1,
        "surface_classes": s1_classes,
        "surface_classes_within_k2": {family: classes_within(q.S1, q.u_S1, limits)
                                      for family, limits in S1_CLASSES.items()},
        "standard_Q0": {family: STANDARD_Q0[name] if name else None for family, name in s1_classes.items()},
        "marking_classes": {"R_L": classify(q.R_L_mcd_m2_lx, R_L_CLASSES), "Qd": classify(q.Qd.value, QD_CLASSES)},
        "marking_classes_within_k2": {"R_L": classes_within(q.R_L_mcd_m2_lx, q.u_R_L_mcd_m2_lx, R_L_CLASSES),
                                      "Qd": classes_within(q.Qd.value, q.Qd.u, QD_CLASSES)},
        "method": q.method,
        "uncertainty": "k = 1; u(Y) = sum |dY/df| u(f): the bound over every correlation of the predicted values",
        "u_correlated": {"R_L_mcd_m2_lx": q.R_L_mcd_m2_lx * q.u_rel_correlated,
                         "Qd_mcd_m2_lx": q.Qd.value * q.u_rel_correlated, "Q0": q.Q0.value * q.u_rel_correlated,
                         "relative": q.u_rel_correlated,
                         "note": "k = 1; the calibrations shared by every point (camera, meter head): one relative "
                                 "shift of R_L, Qd, Q0 and every r value together, apart from the u above; S1 is "
                                 "free of it"},
        "geometry_deg": {"R_L": {"theta_i": R_L_THETA_I_DEG, "theta_o": R_L_THETA_O_DEG, "delta_phi": 0.0},
                         "Qd": {"theta_o": QD_THETA_O_DEG}, "r_table": {"theta_o": R_TABLE_THETA_O_DEG},
                         "phi_o": q.phi_o_deg},
        "rig_version": __version__,
    }


def write_road_json(q: RoadQuantities, out: Path) -> Path:
    """Write road.json under a temporary name, named when complete (never over an existing file); returns its
    path. Quantities left undefined are null in it and named in a warning."""
    out = Path(out)
    document = road_json(q)
    text = json.dumps(document, indent=1, ensure_ascii=False, allow_nan=False) + "\n"
    with new_file(out) as tmp:
        tmp.write_text(text, encoding="utf-8")
    if undefined := document.get("undefined"):
        warnings.warn(f"{out}: {', '.join(undefined['quantities'])} not finite, written as null", stacklevel=2)
    return out


def export_road(predictor: Predictor, out: Path, *, phi_o_deg: float = 0.0) -> Path:
    """road.json of the sample `predictor` describes, at `out` (never overwritten)."""
    return write_road_json(road_quantities(predictor, phi_o_deg=phi_o_deg), out)
