"""BRDF predictors built from a dataset: a fitted model with its covariance, or an interpolant of the
measurements (the interface: rig.analysis.prediction; the command line: `rig predict`, rig/cli/predict.py).

Both assume an isotropic sample (the value depends on θi, θo and the relative azimuth |φo − φi| only), as
the shipped campaigns and the models do; both flag a direction as extrapolated where it lies outside the
measured domain (`MeasuredDomain`).

**interpolate** (the default of `rig predict`: it assumes no model). A goniophotometer measures in
series of one incidence, so the interpolant follows them: within a measured θi, piecewise-linear over a
Delaunay triangulation of the view directions in the projected (Nusselt) disk, (sin θo cos Δφ,
sin θo |sin Δφ|), folded by the isotropic symmetry Δφ ↔ −Δφ; between two measured incidences, linear in
θi, each of the two evaluated at the view that lies in the same place relative to its retroreflection and
mirror points (`lobe_aligned`), so that the lobes are followed as they move with θi. It interpolates ln f,
because the retroreflective and specular peaks span decades (cf. the interpolation schemes reviewed by
Vávra & Filip, and the log-space advice of Dupuy & Jakob 2018).
Its uncertainty combines, in quadrature: the neighbours' u (weighted like the values, i.e. as fully
correlated, which bounds them); within an incidence, the leave-one-out error of the neighbouring
measured points (each interpolated from its own neighbours alone: an upper bound, since removing a point
widens the spacing); between incidences, min(w, 1 − w)·|ln f₁ − ln f₂| of the two bracketing ones.
Outside an incidence's hull it holds the value at the nearest point of the hull's boundary (flagged
`extrapolated`).

**model** (a fitted model: `rig fit --json`, or fitted on the spot). The value is the model's; its u
combines, in quadrature: the parameters' covariance through the model's gradient (delta method, central
differences), scaled up where the points of a series share their errors (`series_correlation_factor`);
the model's misfit to the data, `discrepancy_rel` (the RMS relative residual left once the measurements'
own u is taken out); and the budget components every point shares (camera and meter calibration), which
a fit that treats the points as independent leaves out of its covariance. Only a model can say anything
beyond the measured domain (road quantities at 88.76°, grazing views); such values are still flagged.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.spatial import Delaunay

from rig.analysis.fit import UNUSABLE_FLAGS, choose_weighting, fit_dataset, usable_rows
from rig.analysis.prediction import Prediction
from rig.data.dataset_reader import Dataset
from rig.physics.brdf_models import get_model
from rig.physics.geometry import disk_coordinates, sph_to_vec

#: Measured θi closer than this (degrees) belong to one incidence (achieved angles scatter by ~0.01°).
SAME_INCIDENCE_DEG = 0.5
#: A direction this far (degrees of θi) beyond the measured incidences still counts as inside.
THETA_I_TOLERANCE_DEG = 0.05
#: ...and a view this far (in the projected disk) outside an incidence's hull.
HULL_TOLERANCE = 1e-3
#: Relative step of the central differences of a model's gradient in its parameters.
GRADIENT_STEP_REL = 1e-5
#: Values below this fraction of the median are floored before the log (noise on near-black rows).
LOG_FLOOR_REL = 1e-4


def _as_arrays(*angles_deg: ArrayLike) -> tuple[np.ndarray, ...]:
    return tuple(np.broadcast_arrays(*(np.asarray(a, float) for a in angles_deg)))


@dataclass
class _Incidence:
    """The measured views of one incidence: their triangulation, ln f and relative u."""

    theta_i_deg: float
    mesh: Delaunay
    log_f: np.ndarray
    u_rel: np.ndarray
    u_rel_interp: np.ndarray      # per measured point: its leave-one-out error

    def inside(self, xy: np.ndarray) -> np.ndarray:
        return self.mesh.find_simplex(xy, tol=HULL_TOLERANCE) >= 0

    def evaluate(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """ln f, u_rel (measurements ⊕ interpolation) and inside-ness at disk points (M, 2)."""
        simplex = self.mesh.find_simplex(xy, tol=HULL_TOLERANCE)
        inside = simplex >= 0
        vertices = self.mesh.simplices[np.where(inside, simplex, 0)]
        transform = self.mesh.transform[np.where(inside, simplex, 0)]
        b = np.einsum("mij,mj->mi", transform[:, :2], xy - transform[:, 2])
        weights = np.clip(np.concatenate([b, 1 - b.sum(axis=1, keepdims=True)], axis=1), 0.0, 1.0)
        weights /= weights.sum(axis=1, keepdims=True)
        if not inside.all():
            edge, t = self._nearest_on_hull(xy[~inside])
            vertices[~inside] = np.column_stack([edge, edge[:, 0]])
            weights[~inside] = np.column_stack([1 - t, t, np.zeros_like(t)])
        log_f = (weights * self.log_f[vertices]).sum(axis=1)
        u_meas = (weights * self.u_rel[vertices]).sum(axis=1)
        u_interp = (weights * self.u_rel_interp[vertices]).sum(axis=1)
        return log_f, np.hypot(u_meas, u_interp), inside


    def _nearest_on_hull(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """For disk points outside the hull: the hull edge nearest to each (its two vertices, (M, 2)) and the
        position t ∈ [0, 1] of the nearest point along it. Holding the value there extends the interpolant
        continuously across the hull, as the nearest *vertex* would not: between two rim views the hull's chord
        cuts off a sliver of grazing views, and the nearest vertex may be a view far along the rim in a lobe."""
        edges = self.mesh.convex_hull
        a, b = self.mesh.points[edges[:, 0]], self.mesh.points[edges[:, 1]]
        ab = b - a
        t = np.clip(np.einsum("mhk,hk->mh", xy[:, None, :] - a[None], ab) / np.einsum("hk,hk->h", ab, ab), 0.0, 1.0)
        d2 = (((a[None] + t[..., None] * ab[None]) - xy[:, None, :]) ** 2).sum(axis=2)
        k = np.argmin(d2, axis=1)
        return edges[k], t[np.arange(len(k)), k]


def _loo_errors(mesh: Delaunay, log_f: np.ndarray) -> np.ndarray:
    """|ln f̂ − ln f| at each point from the linear interpolant of the others (0 where that would extrapolate).

    Removing a point changes the triangulation only inside its star, so each point is interpolated from
    a triangulation of its neighbours alone.
    """
    indptr, neighbours = mesh.vertex_neighbor_vertices
    err = np.zeros(len(mesh.points))
    for k in range(len(mesh.points)):
        ring = neighbours[indptr[k]:indptr[k + 1]]
        if len(ring) < 3:
            continue
        try:
            local = Delaunay(mesh.points[ring])
        except Exception:          # collinear neighbours: no interpolation to compare with
            continue
        simplex = int(local.find_simplex(mesh.points[k:k + 1])[0])
        if simplex < 0:            # a point of the hull: the others would extrapolate to it
            continue
        t = local.transform[simplex]
        b = t[:2] @ (mesh.points[k] - t[2])
        w = np.append(b, 1 - b.sum())
        err[k] = abs(float(w @ log_f[ring][local.simplices[simplex]]) - log_f[k])
    return err


def lobe_aligned(xy: np.ndarray, theta_from_deg: np.ndarray, theta_to_deg: float) -> np.ndarray:
    """Disk points (M, 2) of a view at incidence θ_from moved to where the same view *relative to the lobes* lies at
    incidence θ_to: the disk's x axis (the plane of incidence) is mapped piecewise-linearly so that the
    retroreflection point +sin θ and the mirror point −sin θ go from θ_from's to θ_to's, ±1 stay, and each chord
    x = const is scaled onto its image so that the disk's rim stays the rim. Interpolating between incidences at
    these points follows the retro and specular lobes as they move with θi (a simple form of the displacement
    interpolation Radiance's pabopto2bsdf uses between incidences, Ward, Kurt & Bonneel 2014)."""
    s_from, s_to = np.sin(np.radians(theta_from_deg)), np.sin(np.radians(theta_to_deg))
    x, y = xy[:, 0], xy[:, 1]
    safe = np.maximum(s_from, 1e-9)
    inner = x * s_to / safe
    outer = np.sign(x) * (s_to + (np.abs(x) - s_from) * (1 - s_to) / np.maximum(1 - s_from, 1e-9))
    x_new = np.where(s_from < 1e-9, x, np.where(np.abs(x) <= s_from, inner, outer))
    chord_from, chord_to = np.sqrt(np.maximum(1 - x ** 2, 0.0)), np.sqrt(np.maximum(1 - x_new ** 2, 0.0))
    y_new = np.where(chord_from > 1e-12, y * chord_to / np.maximum(chord_from, 1e-12), 0.0)
    return np.stack([x_new, y_new], axis=1)


class MeasuredDomain:
    """The measured incidences and, per incidence, the hull of its views in the projected disk."""

    def __init__(self, incidences: list[_Incidence]):
        if not incidences:
            raise ValueError("no incidence has three or more usable, non-collinear views: nothing to interpolate")
        self.incidences = sorted(incidences, key=lambda inc: inc.theta_i_deg)
        self.theta_i_deg = np.array([inc.theta_i_deg for inc in self.incidences])

    def brackets(self, theta_i_deg: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Per direction: the indices of the incidences below and above, the weight of the upper one, and
        whether θi lies within the measured range."""
        t = self.theta_i_deg
        hi = np.clip(np.searchsorted(t, theta_i_deg), 1, max(len(t) - 1, 1)) if len(t) > 1 else np.zeros(
            theta_i_deg.shape, int)
        lo = np.maximum(hi - 1, 0)
        span = t[hi] - t[lo]
        w = np.where(span > 0, np.clip((theta_i_deg - t[lo]) / np.where(span > 0, span, 1.0), 0.0, 1.0), 0.0)
        within = (theta_i_deg >= t[0] - THETA_I_TOLERANCE_DEG) & (theta_i_deg <= t[-1] + THETA_I_TOLERANCE_DEG)
        return lo, hi, w, within

    def evaluate(self, theta_i_deg: np.ndarray, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """ln f, u_rel and the `extrapolated` flag at flat arrays of θi (M,) and disk points (M, 2)."""
        lo, hi, w, within = self.brackets(theta_i_deg)
        ends = np.zeros((2, len(theta_i_deg)))
        u_rel = np.zeros(len(theta_i_deg))
        inside = within.copy()
        for end, (side, weight) in enumerate(((lo, 1 - w), (hi, w))):
            for k in np.unique(side):
                rows = side == k
                inc = self.incidences[int(k)]
                lf, ur, ins = inc.evaluate(lobe_aligned(xy[rows], theta_i_deg[rows], inc.theta_i_deg))
                ends[end, rows] = lf
                u_rel[rows] += weight[rows] * ur
                inside[rows] &= ins | (weight[rows] == 0)
        log_f = (1 - w) * ends[0] + w * ends[1]
        u_theta = np.minimum(w, 1 - w) * np.abs(ends[1] - ends[0])
        return log_f, np.hypot(u_rel, u_theta), ~inside

    def extrapolated(self, theta_i_deg: np.ndarray, xy: np.ndarray) -> np.ndarray:
        return self.evaluate(theta_i_deg, xy)[2]


def measured_domain(ds: Dataset, exclude_flags: tuple[str, ...] = UNUSABLE_FLAGS,
                    loo_cache: dict[bytes, np.ndarray] | None = None) -> MeasuredDomain:
    """Group a dataset's usable rows by incidence and triangulate each group's views.

    `loo_cache`: leave-one-out errors by incidence content, kept by a caller that rebuilds the domain as rows
    arrive (adaptive sampling adds one incidence's views at a time; the others need not be redone)."""
    keep = usable_rows(ds, exclude_flags) & np.isfinite(ds["brdf_per_sr"])
    theta_i, f = ds["theta_i_deg"][keep], ds["brdf_per_sr"][keep]
    u = ds["u_brdf_per_sr"][keep] if "u_brdf_per_sr" in ds.columns else np.full(f.shape, np.nan)
    xy = disk_coordinates(ds["theta_o_deg"][keep], ds["phi_o_deg"][keep], ds["phi_i_deg"][keep])
    floor = LOG_FLOOR_REL * float(np.median(np.abs(f))) if f.size else 1.0
    log_f = np.log(np.maximum(f, floor))
    u_rel = np.where(np.isfinite(u) & (u > 0), u / np.maximum(f, floor), 0.0)
    order = np.argsort(theta_i)
    groups: list[list[int]] = []
    for k in order:
        if groups and theta_i[k] - theta_i[groups[-1][0]] <= SAME_INCIDENCE_DEG:
            groups[-1].append(int(k))
        else:
            groups.append([int(k)])
    incidences = []
    for rows in groups:
        points, _ = np.unique(xy[rows].round(12), axis=0, return_index=True)
        if len(points) < 3:
            continue
        rows_a = np.array(rows)
        try:
            mesh = Delaunay(xy[rows_a])
        except Exception:          # collinear views (a single plane of incidence): no 2-D interpolant
            continue
        key = xy[rows_a].tobytes() + log_f[rows_a].tobytes()
        loo = loo_cache.get(key) if loo_cache is not None else None
        if loo is None:
            loo = _loo_errors(mesh, log_f[rows_a])
            if loo_cache is not None:
                loo_cache[key] = loo
        incidences.append(_Incidence(float(np.mean(theta_i[rows_a])), mesh, log_f[rows_a], u_rel[rows_a],
                                     loo))
    return MeasuredDomain(incidences)


class InterpolatingPredictor:
    """The measurements, interpolated (module docstring)."""

    method = "interpolate: piecewise-linear in ln f over each incidence's views, linear in θi between them"

    def __init__(self, domain: MeasuredDomain):
        self.domain = domain

    def predict(self, theta_i_deg: ArrayLike, phi_i_deg: ArrayLike, theta_o_deg: ArrayLike,
                phi_o_deg: ArrayLike) -> Prediction:
        ti, pi_, to, po = _as_arrays(theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg)
        shape = ti.shape
        log_f, u_rel, extrapolated = self.domain.evaluate(ti.ravel(), disk_coordinates(to, po, pi_).reshape(-1, 2))
        f = np.exp(log_f)
        return Prediction(f.reshape(shape), (f * u_rel).reshape(shape), extrapolated.reshape(shape))


@dataclass(frozen=True)
class FittedModel:
    """A model's parameters and their covariance (free parameters only)."""

    model: str
    params: Mapping[str, float]
    covariance: Mapping[str, Mapping[str, float | None]]

    @classmethod
    def from_json(cls, fit: Mapping[str, Any], source: str = "<fit>") -> FittedModel:
        """What `rig fit --json` writes; ValueError names what is missing."""
        try:
            model, params = str(fit["model"]), {k: float(v) for k, v in fit["params"].items()}
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            raise ValueError(f"{source}: not a fit result of `rig fit --json` (needs model and params): {exc}") \
                from None
        get_model(model)
        return cls(model, params, fit.get("covariance") or {})

    def covariance_matrix(self) -> tuple[tuple[str, ...], np.ndarray]:
        """The free parameters and their covariance; undetermined (null or inf) entries become inf."""
        names = tuple(self.covariance)
        cov = np.array([[np.inf if (v := self.covariance[p].get(q)) is None else float(v) for q in names]
                        for p in names], float).reshape(len(names), len(names))
        return names, cov


class ModelPredictor:
    """A fitted model (module docstring)."""

    def __init__(self, fitted: FittedModel, domain: MeasuredDomain | None, discrepancy_rel: float = 0.0,
                 scale_u_rel: float = 0.0, covariance_factor: float = 1.0):
        self.fitted = fitted
        self.covariance_factor = covariance_factor
        self.model = get_model(fitted.model)
        self.domain = domain
        self.discrepancy_rel = discrepancy_rel
        self.scale_u_rel = scale_u_rel
        self.method = (f"model {fitted.model} (fitted; u from the parameters' covariance, a misfit of "
                       f"{100 * discrepancy_rel:.2g} % and a common scale u of {100 * scale_u_rel:.2g} %)")

    def _value(self, wi: np.ndarray, wo: np.ndarray, params: Mapping[str, float]) -> np.ndarray:
        with np.errstate(all="ignore"):
            return self.model.evaluate(wi, wo, **params)

    def predict(self, theta_i_deg: ArrayLike, phi_i_deg: ArrayLike, theta_o_deg: ArrayLike,
                phi_o_deg: ArrayLike) -> Prediction:
        ti, pi_, to, po = _as_arrays(theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg)
        wi = sph_to_vec(np.radians(ti), np.radians(pi_))
        wo = sph_to_vec(np.radians(to), np.radians(po))
        params = dict(self.fitted.params)
        f = self._value(wi, wo, params)
        names, cov = self.fitted.covariance_matrix()
        grad = np.zeros((*f.shape, len(names)))
        for k, name in enumerate(names):
            h = GRADIENT_STEP_REL * max(abs(params[name]), 1e-300)
            up, down = self._value(wi, wo, {**params, name: params[name] + h}), \
                self._value(wi, wo, {**params, name: params[name] - h})
            grad[..., k] = (up - down) / (2 * h)
        with np.errstate(invalid="ignore"):
            var = self.covariance_factor * np.einsum("...i,ij,...j->...", grad, cov, grad) if names else \
                np.zeros(f.shape)
        u = np.sqrt(np.maximum(var, 0.0) + ((self.discrepancy_rel ** 2 + self.scale_u_rel ** 2) * f ** 2))
        u = np.where(np.isnan(var), np.inf, u)
        if self.domain is None:
            extrapolated = np.ones(f.shape, bool)
        else:
            extrapolated = self.domain.extrapolated(ti.ravel(), disk_coordinates(to, po, pi_).reshape(-1, 2))
        return Prediction(f, u, extrapolated.reshape(f.shape))


def series_correlation_factor(ds: Dataset, fitted: FittedModel,
                              exclude_flags: tuple[str, ...] = UNUSABLE_FLAGS) -> float:
    """How much the fit's covariance understates, because the points of one series share errors (their E⊥
    reading, the texture of neighbouring views) that a fit takes as independent: n·mean(r)² of each series'
    relative residuals r, averaged over the series, over the mean r². About 1 for independent residuals;
    ≥ 1 always (a fit's covariance is never shrunk)."""
    keep = usable_rows(ds, exclude_flags) & (ds["brdf_per_sr"] > 0)
    if not keep.any() or "series" not in ds.columns:
        return 1.0
    wi, wo = ds.directions()
    with np.errstate(all="ignore"):
        r = get_model(fitted.model).evaluate(wi[keep], wo[keep], **fitted.params) / ds["brdf_per_sr"][keep] - 1
    series = ds["series"][keep]
    blocks = [r[series == s] for s in np.unique(series)]
    spread = float(np.mean(r ** 2))
    if not spread > 0:
        return 1.0
    return max(1.0, float(np.mean([len(b) * np.mean(b) ** 2 for b in blocks])) / spread)


def model_discrepancy_rel(ds: Dataset, fitted: FittedModel, exclude_flags: tuple[str, ...] = UNUSABLE_FLAGS) -> float:
    """RMS relative residual of the model on the dataset beyond the measurements' own relative u (≥ 0)."""
    keep = usable_rows(ds, exclude_flags) & (ds["brdf_per_sr"] > 0)
    if not keep.any():
        return 0.0
    wi, wo = ds.directions()
    with np.errstate(all="ignore"):
        model = get_model(fitted.model).evaluate(wi[keep], wo[keep], **fitted.params)
    f = ds["brdf_per_sr"][keep]
    u = ds["u_brdf_per_sr"][keep] if "u_brdf_per_sr" in ds.columns else np.zeros(f.shape)
    u = np.where(np.isfinite(u), u, 0.0)
    excess = np.mean(((model - f) / f) ** 2) - np.mean((u / f) ** 2)
    return float(np.sqrt(max(excess, 0.0)))


#: Budget components that every point of a run shares (the camera's calibration, the meter's): a fit treats
#: the points as independent, so its covariance leaves them out.
COMMON_COMPONENTS = ("u_rel_calibration", "u_rel_illuminance")


def common_scale_u_rel(ds: Dataset) -> float:
    """The median over the rows of the budget components all points share (0 where a dataset has none)."""
    parts = [ds[c] for c in COMMON_COMPONENTS if c in ds.columns]
    if not parts or len(ds) == 0:
        return 0.0
    total = np.sqrt(np.nansum(np.square(parts), axis=0))
    return float(np.median(total))


def model_predictor(ds: Dataset, fit: Mapping[str, Any] | None = None, model: str | None = None,
                    source: str = "<fit>") -> ModelPredictor:
    """A ModelPredictor from a `rig fit --json` result, or from fitting `model` to `ds` now."""
    if fit is None:
        if model is None:
            raise ValueError("the model method needs a fit (--fit FIT.json) or a model to fit (--model NAME)")
        keep = usable_rows(ds)
        weighting, _ = choose_weighting(ds["u_brdf_per_sr"][keep], [i for i, k in zip(ds.point_id, keep) if k], None)
        fit = fit_dataset(ds, model, weighting=weighting).to_json()
    fitted = FittedModel.from_json(fit, source)
    return ModelPredictor(fitted, measured_domain(ds), model_discrepancy_rel(ds, fitted), common_scale_u_rel(ds),
                          series_correlation_factor(ds, fitted))
