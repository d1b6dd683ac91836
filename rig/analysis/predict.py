"""BRDF predictors built from a dataset: a fitted model with its covariance, or an interpolant of the
measurements (the interface: rig.analysis.prediction; the command line: `rig predict`, rig/cli/predict.py).

Both assume an isotropic sample (the value depends on θi, θo and the relative azimuth |φo − φi| only), as
the shipped campaigns and the models do; both flag a direction as extrapolated where it lies outside the
measured domain (`MeasuredDomain`).

**interpolate** (the default of `rig predict`: it assumes no model). A goniophotometer measures in
series of one incidence, so the interpolant follows them: within a measured θi, piecewise-linear over a
Delaunay triangulation of the view directions in the projected (Nusselt) disk, (sin θo cos Δφ,
sin θo |sin Δφ|), folded by the isotropic symmetry Δφ ↔ −Δφ and triangulated with their mirror images so
that it is continuous across the plane of incidence (rig.analysis.incidence_views); between two measured
incidences, linear in θi, each of the two evaluated at the view that lies in the same place relative to its
retroreflection and mirror points (`lobe_aligned`), so that the lobes are followed as they move with θi. It
interpolates ln f, because the retroreflective and specular peaks span decades (cf. the interpolation
schemes reviewed by Vávra & Filip, and the log-space advice of Dupuy & Jakob 2018).
Its uncertainty combines, in quadrature: the neighbours' u (weighted like the values, i.e. as fully
correlated, which bounds them); within an incidence, the interpolation error from the curvature that
leave-one-out errors show, and beyond its hull the slope of ln f times the distance; between incidences,
min(w, 1 − w)·|ln f₁ − ln f₂| of the two bracketing ones and the bend a third incidence shows; beyond the
measured θi range, the slope in θi times the distance (`MeasuredDomain.evaluate`; docs/predict.md).
Outside an incidence's hull it holds the value at the nearest point of the hull's boundary (flagged
`extrapolated`).

**model** (a fitted model: `rig fit --json`, or fitted on the spot). The value is the model's; its u
combines, in quadrature: the parameters' covariance through the model's gradient (delta method, central
differences), scaled up where the points of a series share their errors (`series_correlation_factor`);
the model's misfit to the data, `discrepancy_rel` (the RMS relative residual left once the measurements'
own u is taken out); and the budget components every point shares (camera and meter calibration), which
a fit that treats the points as independent leaves out of its covariance; and, beyond the measured domain,
a model-form term: the model against the data's own extrapolation (the interpolant's, which holds the nearest
measured values), |f_model − f_data|. Only a model can say anything beyond the measured domain (road
quantities at 88.76°, grazing views), but there nothing measured confirms its shape: two reconstructions that
agree where they were measured and part beyond it say how much is not known. Such values are flagged.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from rig.analysis.fit import UNUSABLE_FLAGS, choose_weighting, fit_dataset, usable_rows
from rig.analysis.incidence_views import IncidenceViews, incidence_views
from rig.analysis.prediction import Prediction
from rig.data.dataset_reader import Dataset
from rig.physics.brdf_models import get_model
from rig.physics.geometry import disk_coordinates, sph_to_vec

#: Measured θi closer than this (degrees) belong to one incidence (achieved angles scatter by ~0.01°).
SAME_INCIDENCE_DEG = 0.5
#: A direction this far (degrees of θi) beyond the measured incidences still counts as inside.
THETA_I_TOLERANCE_DEG = 0.05
#: Relative step of the central differences of a model's gradient in its parameters.
GRADIENT_STEP_REL = 1e-5
#: Values below this fraction of the median are floored before the log (noise on near-black rows).
LOG_FLOOR_REL = 1e-4


def _as_arrays(*angles_deg: ArrayLike) -> tuple[np.ndarray, ...]:
    return tuple(np.broadcast_arrays(*(np.asarray(a, float) for a in angles_deg)))


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

    def __init__(self, incidences: list[IncidenceViews], aligned: bool = True, theta_u_scale: float = 1.0):
        """`aligned`: between incidences, views are compared relative to the lobes (`lobe_aligned`), else at fixed
        (θo, Δφ); `theta_u_scale`: the between-incidence terms of u are multiplied by it (a calibration on held-out
        incidences, rig.analysis.held_out)."""
        if not incidences:
            raise ValueError("no incidence has three or more usable, non-collinear views: nothing to interpolate")
        self.incidences = sorted(incidences, key=lambda inc: inc.theta_i_deg)
        self.theta_i_deg = np.array([inc.theta_i_deg for inc in self.incidences])
        self.aligned, self.theta_u_scale = aligned, theta_u_scale

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
        f_lo, u_lo, in_lo = self.at_incidence(lo, theta_i_deg, xy)
        f_hi, u_hi, in_hi = self.at_incidence(hi, theta_i_deg, xy)
        inside = within & (in_lo | (w == 1)) & (in_hi | (w == 0))
        log_f = (1 - w) * f_lo + w * f_hi
        u_theta = self.theta_u_scale * np.hypot(np.minimum(w, 1 - w) * np.abs(f_hi - f_lo),
                                                 self.theta_bend(theta_i_deg, xy, lo, hi, w, f_lo, f_hi))
        u_rel = np.hypot((1 - w) * u_lo + w * u_hi, u_theta)
        return log_f, np.hypot(u_rel, self._beyond(theta_i_deg, xy, f_lo)), ~inside

    def at_incidence(self, k: np.ndarray, theta_i_deg: np.ndarray, xy: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """ln f, u_rel and inside-ness of measured incidence k[m] at the view xy[m] of incidence θi[m] (lobe-aligned
        unless the domain is not `aligned`)."""
        out = np.zeros(len(k)), np.zeros(len(k)), np.zeros(len(k), bool)
        for j in np.unique(k):
            rows = k == j
            inc = self.incidences[int(j)]
            at = lobe_aligned(xy[rows], theta_i_deg[rows], inc.theta_i_deg) if self.aligned else xy[rows]
            for array, part in zip(out, inc.evaluate(at)):
                array[rows] = part
        return out

    def theta_bend(self, theta_i_deg: np.ndarray, xy: np.ndarray, lo: np.ndarray, hi: np.ndarray, w: np.ndarray,
              f_lo: np.ndarray, f_hi: np.ndarray) -> np.ndarray:
        """How far the straight line in θi between the two bracketing incidences may be off: |quadratic − linear|
        in ln f, the quadratic through the brackets and the next incidence beyond either (the larger of the two),
        at the lobe-aligned view. Zero at a measured incidence and where fewer than three are measured. The term
        min(w, 1 − w)·|Δ ln f| is blind to a change both brackets agree on (the diffuse floor rising towards
        grazing views at another rate than the lobes' tails fall, say); the bend over three incidences is what
        linear interpolation leaves out."""
        t = self.theta_i_deg
        out = np.zeros(len(theta_i_deg))
        for c in (lo - 1, hi + 1):
            rows = np.flatnonzero((w > 0) & (w < 1) & (c >= 0) & (c < len(t)))
            if not rows.size:
                continue
            x, ta, tb, tc = theta_i_deg[rows], t[lo[rows]], t[hi[rows]], t[c[rows]]
            f_c = self.at_incidence(c[rows], x, xy[rows])[0]
            quadratic = (f_lo[rows] * (x - tb) * (x - tc) / ((ta - tb) * (ta - tc))
                         + f_hi[rows] * (x - ta) * (x - tc) / ((tb - ta) * (tb - tc))
                         + f_c * (x - ta) * (x - tb) / ((tc - ta) * (tc - tb)))
            linear = (1 - w[rows]) * f_lo[rows] + w[rows] * f_hi[rows]
            out[rows] = np.maximum(out[rows], np.abs(quadratic - linear))
        return out

    def _beyond(self, theta_i_deg: np.ndarray, xy: np.ndarray, f_end: np.ndarray) -> np.ndarray:
        """Beyond the measured θi range the value of the last incidence is held; it may be off by the slope in θi
        between the last two incidences (at the lobe-aligned view) times the distance. With one incidence nothing
        says how fast the value changes with θi: half the range of its ln f, whatever the distance."""
        t = self.theta_i_deg
        out = np.zeros(len(theta_i_deg))
        for end, (past, nxt) in enumerate(((0, 1), (len(t) - 1, len(t) - 2))):
            distance = (t[0] - theta_i_deg) if end == 0 else (theta_i_deg - t[-1])
            rows = np.flatnonzero(distance > THETA_I_TOLERANCE_DEG)
            if not rows.size:
                continue
            if len(t) < 2:
                out[rows] = 0.5 * np.ptp(self.incidences[0].log_f)
                continue
            f_next = self.at_incidence(np.full(rows.size, nxt), theta_i_deg[rows], xy[rows])[0]
            slope = np.abs(f_end[rows] - f_next) / abs(t[past] - t[nxt])
            out[rows] = slope * distance[rows]
        return out

    def extrapolated(self, theta_i_deg: np.ndarray, xy: np.ndarray) -> np.ndarray:
        return self.evaluate(theta_i_deg, xy)[2]


def measured_domain(ds: Dataset, exclude_flags: tuple[str, ...] = UNUSABLE_FLAGS,
                    loo_cache: dict[bytes, np.ndarray] | None = None) -> MeasuredDomain:
    """Group a dataset's usable rows by incidence and triangulate each group's views.

    `loo_cache`: leave-one-out curvatures by incidence content, kept by a caller that rebuilds the domain as rows
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
        r = np.array(rows)
        inc = incidence_views(float(np.mean(theta_i[r])), xy[r], log_f[r], u_rel[r], loo_cache)
        if inc is not None:
            incidences.append(inc)
    return MeasuredDomain(incidences)


class InterpolatingPredictor:
    """The measurements, interpolated (module docstring)."""

    def __init__(self, domain: MeasuredDomain, method: str = ""):
        self.domain = domain
        self.method = method or ("interpolate: piecewise-linear in ln f over each incidence's views, linear in θi "
                                 "between them" + (" at lobe-aligned views" if domain.aligned else ""))

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
            return Prediction(f, u, np.ones(f.shape, bool))
        log_f_data, _, extrapolated = self.domain.evaluate(ti.ravel(), disk_coordinates(to, po, pi_).reshape(-1, 2))
        extrapolated = extrapolated.reshape(f.shape)
        with np.errstate(all="ignore"):
            form = np.where(extrapolated, np.abs(f - np.exp(log_f_data.reshape(f.shape))), 0.0)
        return Prediction(f, np.hypot(u, np.where(np.isfinite(form), form, np.inf)), extrapolated)


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
