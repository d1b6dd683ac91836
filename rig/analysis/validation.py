"""The error of a dataset as a representation of the BRDF: its predictor against the truth, on directions it
did not measure (issue 15; the method follows the planning digest in docs/sampling.md).

On the simulated rig the truth is known. A *validation set* of (ωi, ωo) pairs covers the domain the rig can
measure (θi in the campaign's range, θo up to the campaign's view limit, outside the lamp's occlusion cone):
a scrambled Sobol sequence stratified in projected solid angle (sin²θ uniform, as Nielsen et al. 2015 weigh
BRDF space), plus extra pairs in the retroreflection cone, the specular cone and at grazing incidence, where
road-marking BRDFs change fastest. Pairs within `DISJOINT_DEG` of a measured pair are dropped, so a predictor
is never scored on its own nodes.

Per pair the error is e = |ln((f̂ + τ)/(f + τ))| (log-relative, as in Nielsen et al. 2015 and Low et al. 2012:
the peaks span decades), with τ = `TAU_REL` × the median true value in the diffuse region, so that near-black
regions do not dominate. It is summarised by median, p95 and max per region: *retro* (ωo within `RETRO_DEG`
of ωi), *forward* (ωo within `FORWARD_DEG` of the mirror direction), *diffuse* (the rest).

Where a *reference* is given (the measured domain of the dataset a strategy is compared with, e.g. the paper's
table), the regions are scored only on the pairs inside it, and the pairs it never measured (the specular cone
at high θi, forward views at grazing incidence, the occlusion cone's rim) are summarised apart as *blind*: no
strategy can be judged where the reference itself extrapolates, and pooled with the rest they decide the p95 as
soon as they exceed 5 % of the set (a table and an adaptive run at a quarter of its time once scored 1.264 and
1.264 pooled, 0.114 and 0.330 inside the table's hull). Task quantities
are compared as relative errors: the directional albedo ∫ f cos θo dωo over the measurable views, per θi, and
the road-lighting quantities R_L and Qd (rig.analysis.road; both lie beyond the rig's reach, so a model-free
predictor extrapolates them and says so).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import cKDTree

from rig.analysis.prediction import Prediction, Predictor
from rig.analysis.road import cap_quadrature, road_quantities
from rig.physics import geometry as geo
from rig.physics.brdf_models import get_model

REGIONS = ("diffuse", "forward", "retro")
#: Half-angle (degrees) of the retroreflection cone around ωi, and of the specular cone around the mirror direction.
RETRO_DEG = 10.0
FORWARD_DEG = 15.0
#: Extra validation pairs are drawn within these cones (degrees) and in the top `GRAZING_SPAN_DEG` of θi.
RETRO_EXTRA_DEG = 5.0
FORWARD_EXTRA_DEG = 10.0
GRAZING_SPAN_DEG = 15.0
#: A validation pair closer than this (degrees, in ωi and in ωo) to a measured pair is left out.
DISJOINT_DEG = 0.25
#: τ of the log error, relative to the median true value of the diffuse region.
TAU_REL = 0.01


@dataclass(frozen=True)
class Domain:
    """What the rig can measure: θi range (degrees), the view limit θo ≤ theta_o_max_deg, and the lamp's occlusion
    cone around ωi (views closer than occlusion_deg to the incidence are never seen)."""

    theta_i_min_deg: float
    theta_i_max_deg: float
    theta_o_max_deg: float
    occlusion_deg: float


@dataclass(frozen=True)
class ValidationSet:
    angles_deg: np.ndarray          # (N, 4): θi, φi, θo, φo
    region: np.ndarray              # (N,) one of REGIONS


class TruthPredictor:
    """A BRDF model with known parameters as a Predictor: exact, u = 0, never extrapolated."""

    def __init__(self, model: str, params: Mapping[str, float]):
        self.model, self.params = get_model(model), dict(params)
        self.method = f"truth: {model}"

    def predict(self, theta_i_deg: ArrayLike, phi_i_deg: ArrayLike, theta_o_deg: ArrayLike,
                phi_o_deg: ArrayLike) -> Prediction:
        ti, pi_, to, po = np.broadcast_arrays(*(np.asarray(a, float) for a in (theta_i_deg, phi_i_deg, theta_o_deg,
                                                                                 phi_o_deg)))
        wi = geo.sph_to_vec(np.radians(ti), np.radians(pi_))
        wo = geo.sph_to_vec(np.radians(to), np.radians(po))
        f = np.asarray(self.model(wi.reshape(-1, 3), wo.reshape(-1, 3), self.params), float).reshape(ti.shape)
        return Prediction(f, np.zeros_like(f), np.zeros(f.shape, bool))


def _directions(unit_sin2: np.ndarray, unit_phi: np.ndarray, theta_min_deg: float,
                theta_max_deg: float) -> np.ndarray:
    """Unit vectors uniform in projected solid angle over the band θ ∈ [θmin, θmax] for uniform inputs in [0, 1)."""
    lo, hi = np.sin(np.radians(theta_min_deg)) ** 2, np.sin(np.radians(theta_max_deg)) ** 2
    theta = np.arcsin(np.sqrt(lo + unit_sin2 * (hi - lo)))
    return geo.sph_to_vec(theta, 2 * np.pi * unit_phi)


def _about(centre: np.ndarray, max_deg: float, unit_a: np.ndarray, unit_b: np.ndarray) -> np.ndarray:
    """Directions uniform in solid angle within max_deg of each centre (N, 3), in a frame built per centre."""
    cos_a = 1.0 - unit_a * (1.0 - np.cos(np.radians(max_deg)))
    sin_a, b = np.sqrt(1.0 - cos_a ** 2), 2 * np.pi * unit_b
    helper = np.where(np.abs(centre[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t1 = np.cross(centre, helper)
    t1 /= np.linalg.norm(t1, axis=1, keepdims=True)
    t2 = np.cross(centre, t1)
    return cos_a[:, None] * centre + sin_a[:, None] * (np.cos(b)[:, None] * t1 + np.sin(b)[:, None] * t2)


def region_of(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """'retro', 'forward' or 'diffuse' per pair of unit vectors (N, 3)."""
    retro = np.degrees(geo.angle_between(wi, wo)) < RETRO_DEG
    forward = np.degrees(geo.angle_between(wo, geo.mirror_direction(wi))) < FORWARD_DEG
    return np.where(retro, "retro", np.where(forward, "forward", "diffuse"))


def validation_set(domain: Domain, n_base: int = 4096, seed: int = 0,
                   measured_deg: np.ndarray | None = None) -> ValidationSet:
    """Stratified pairs over `domain` (n_base of them) plus n_base/4 each in the retro cone, the specular cone and
    at grazing incidence; pairs outside the domain and near a measured pair (`measured_deg`, (M, 4)) are dropped."""
    from scipy.stats import qmc  # here: scipy.stats costs ~0.7 s to import, and only the bench needs it

    sobol = qmc.Sobol(d=6, scramble=True, seed=seed)
    m = int(np.ceil(np.log2(max(n_base, 2))))
    base = sobol.random_base2(m)[:n_base]
    extra = sobol.random(3 * max(n_base // 4, 1)).reshape(3, -1, 6)
    d = domain
    wi = [_directions(base[:, 0], base[:, 1], d.theta_i_min_deg, d.theta_i_max_deg)]
    wo = [_directions(base[:, 2], base[:, 3], 0.0, d.theta_o_max_deg)]
    for part, u in zip(("retro", "forward", "grazing"), extra):
        grazing_min = max(d.theta_i_min_deg, d.theta_i_max_deg - GRAZING_SPAN_DEG)
        w_i = _directions(u[:, 0], u[:, 1], grazing_min if part == "grazing" else d.theta_i_min_deg,
                          d.theta_i_max_deg)
        if part == "retro":
            w_o = _about(w_i, RETRO_EXTRA_DEG, u[:, 2], u[:, 3])
        elif part == "forward":
            w_o = _about(geo.mirror_direction(w_i), FORWARD_EXTRA_DEG, u[:, 2], u[:, 3])
        else:
            w_o = _directions(u[:, 2], u[:, 3], 0.0, d.theta_o_max_deg)
        wi.append(w_i)
        wo.append(w_o)
    w_i, w_o = np.concatenate(wi), np.concatenate(wo)
    theta_o_deg = np.degrees(np.arccos(np.clip(w_o[:, 2], -1.0, 1.0)))
    keep = (w_o[:, 2] > 1e-9) & (theta_o_deg <= d.theta_o_max_deg) \
        & (np.degrees(geo.angle_between(w_i, w_o)) >= d.occlusion_deg)
    if measured_deg is not None and len(measured_deg):
        keep &= ~_near_measured(w_i, w_o, np.asarray(measured_deg, float))
    w_i, w_o = w_i[keep], w_o[keep]
    ti, pi_ = geo.vec_to_sph(w_i)
    to, po = geo.vec_to_sph(w_o)
    angles = np.degrees(np.stack([ti, pi_, to, po], axis=1))
    return ValidationSet(angles, region_of(w_i, w_o))


def _near_measured(wi: np.ndarray, wo: np.ndarray, measured_deg: np.ndarray) -> np.ndarray:
    """Pairs within DISJOINT_DEG of some measured pair in both directions (a k-d tree on the stacked vectors:
    the chord of the 6-vector bounds each direction's chord)."""
    r = np.radians(measured_deg)
    measured = np.hstack([geo.sph_to_vec(r[:, 0], r[:, 1]), geo.sph_to_vec(r[:, 2], r[:, 3])])
    chord = 2 * np.sin(np.radians(DISJOINT_DEG) / 2)
    hits = cKDTree(measured).query_ball_point(np.hstack([wi, wo]), np.sqrt(2) * chord)
    near = np.zeros(len(wi), bool)
    for k, found in enumerate(hits):
        for j in found:
            if np.linalg.norm(wi[k] - measured[j, :3]) <= chord and np.linalg.norm(wo[k] - measured[j, 3:]) <= chord:
                near[k] = True
                break
    return near


def log_errors(f_hat: ArrayLike, f_true: ArrayLike, tau: float) -> np.ndarray:
    """|ln((f̂ + τ)/(f + τ))|: a relative error that a near-black region cannot blow up (f̂ < −τ counts as −τ/2)."""
    estimate = np.maximum(np.asarray(f_hat, float), -tau / 2)
    return np.abs(np.log((estimate + tau) / (np.asarray(f_true, float) + tau)))


@dataclass(frozen=True)
class RegionError:
    n: int
    median: float
    p95: float
    max: float


def summarise(errors: np.ndarray, region: np.ndarray) -> dict[str, RegionError]:
    """Median, p95 and max of the errors per region (and 'all'); a region without pairs has NaN statistics."""
    out = {}
    for name in (*REGIONS, "all"):
        e = errors if name == "all" else errors[region == name]
        stats = np.percentile(e, [50, 95, 100]) if e.size else np.full(3, np.nan)
        out[name] = RegionError(int(e.size), float(stats[0]), float(stats[1]), float(stats[2]))
    return out


def albedo_per_incidence(predictor: Predictor, theta_i_deg: np.ndarray, theta_o_max_deg: float,
                         n: int = 48) -> np.ndarray:
    """∫ f cos θo dωo over the views θo ≤ θo_max, at each θi (φi = 0): the directional albedo the rig can see."""
    theta_o, dphi, w = cap_quadrature(theta_o_max_deg, n)
    w = w * np.cos(np.radians(theta_o))
    out = []
    for ti in np.atleast_1d(theta_i_deg):
        p = predictor.predict(ti, 0.0, theta_o, 180.0 + dphi)    # nodes cluster in the plane of incidence
        out.append(float(np.sum(w * p.brdf_per_sr)))
    return np.array(out)


@dataclass(frozen=True)
class RepresentationError:
    tau_per_sr: float
    regions: dict[str, RegionError]
    albedo_rel: np.ndarray          # relative error of the directional albedo at `albedo_theta_i_deg`
    albedo_theta_i_deg: np.ndarray
    road_rel: dict[str, float]      # relative error of R_L and Qd
    road_extrapolated: bool
    blind: RegionError | None = None  # the pairs outside the reference's measured domain, when one was given

    def row(self) -> dict[str, float]:
        """Flat figures for a table: median/p95 per region (inside the reference, when one was given), the blind
        pairs' count and p95, worst albedo error, road errors."""
        out: dict[str, float] = {}
        for name, r in self.regions.items():
            out[f"{name}_median"], out[f"{name}_p95"] = r.median, r.p95
        if self.blind is not None:
            out["blind_n"], out["blind_p95"] = float(self.blind.n), self.blind.p95
        out["albedo_max_rel"] = float(np.max(np.abs(self.albedo_rel))) if self.albedo_rel.size else float("nan")
        out.update({f"{k}_rel": v for k, v in self.road_rel.items()})
        return out


def representation_error(predictor: Predictor, truth: Predictor, vset: ValidationSet, domain: Domain,
                         albedo_step_deg: float = 5.0, road: bool = True,
                         reference: Predictor | None = None) -> RepresentationError:
    """The predictor's errors against the truth on the validation set and on the task quantities; with a
    `reference`, the regions only where the reference's own prediction is not extrapolated (module docstring)."""
    a = vset.angles_deg
    f_true = truth.predict(a[:, 0], a[:, 1], a[:, 2], a[:, 3]).brdf_per_sr
    f_hat = predictor.predict(a[:, 0], a[:, 1], a[:, 2], a[:, 3]).brdf_per_sr
    diffuse = f_true[vset.region == "diffuse"]
    tau = TAU_REL * float(np.median(diffuse if diffuse.size else f_true))
    errors = log_errors(f_hat, f_true, tau)
    blind = None
    if reference is not None:
        seen = ~np.asarray(reference.predict(a[:, 0], a[:, 1], a[:, 2], a[:, 3]).extrapolated, bool)
        blind = summarise(errors[~seen], vset.region[~seen])["all"]
        errors, region = errors[seen], vset.region[seen]
    else:
        region = vset.region
    regions = summarise(errors, region)
    theta_i = np.arange(domain.theta_i_min_deg, domain.theta_i_max_deg + 1e-9, albedo_step_deg)
    a_true = albedo_per_incidence(truth, theta_i, domain.theta_o_max_deg)
    a_hat = albedo_per_incidence(predictor, theta_i, domain.theta_o_max_deg)
    road_rel: dict[str, float] = {}
    extrapolated = False
    if road:
        q_true, q_hat = road_quantities(truth, n=32), road_quantities(predictor, n=32)
        road_rel = {"R_L": q_hat.R_L_mcd_m2_lx / q_true.R_L_mcd_m2_lx - 1.0,
                    "Qd": q_hat.Qd.value / q_true.Qd.value - 1.0}
        extrapolated = bool(q_hat.R_L_extrapolated or q_hat.Qd.extrapolated_share > 0)
    return RepresentationError(tau, regions, a_hat / a_true - 1.0, theta_i, road_rel, extrapolated, blind)
