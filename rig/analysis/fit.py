"""Fit a registry BRDF model to measured data: `fit`, `fit_dataset` (the `rig fit` command line: rig/cli/fit.py).

Why it is built this way (Spieringhs et al. 2023 fitted with a genetic algorithm;
their parameters span 1e-12 to 1.65e4, Tables 3 and 6 of the paper):

* every free parameter lives on the unit cube: log-uniform between its bounds when the
  model lists it in `log_scale` (exponents, tiny coefficients), affine otherwise, so one
  finite-difference step and one Latin hypercube fit all of them and bounds stay reachable;
* global stage (rig/analysis/fit_search.py): on a subsample, `differential_evolution` (a
  Latin-hypercube population seeded with the model's `typical` values), then bounded
  `least_squares` from its best distinct members, from `typical` and from a seeded Sobol set
  spread over the whole cube; the best distinct optima are refined on all points and the best of
  those polished. Plateaus where a lobe is too narrow to be seen trap local starts, the population
  and the spread starts do not; how many of the runs reached the best cost is reported;
* residuals are weighted by `u_brdf_per_sr` (χ² with a meaningful χ²/dof) or unweighted
  (the paper's RMSE); `rig fit` chooses by the data (`choose_weighting`): weighted when every row
  has a usable u, unweighted with a notice when none has (an imported ALTA file without #VS),
  refused when only some have; robust losses (soft_l1, huber) take a scale estimated from the
  residuals' MAD, so outliers (glints, dust) cost linearly while the noise keeps its
  quadratic cost; a blind zone around retroreflection needs nothing special: the lobe's
  shoulders carry its width and height;
* the covariance and standard errors come from the Jacobian at the optimum through the delta method, scaled
  by the residual variance (unweighted), the MAD² (robust) or max(1, χ²/dof) (weighted);
  directions the data do not constrain (a null space of the Jacobian) give `inf`, never NaN;
* RMSE, NRMSE and NCC are always computed on the unweighted values (rig.analysis.metrics);
* a dataset's weights are its point-to-point u (`u_brdf_point_per_sr`, issue 34): the calibrations shared by
  every point (rig.physics.budget.CORRELATED_COMPONENTS) do not scatter the points about the model, they move
  them together, so they go to `stderr_correlated` instead: each shared relative error δ·s_k (one per
  source: the calibrations of camera and meter, the axes' zeros, each filter's transmission) moves the
  optimum by the linear response Δx = J⁺ (s f / σ), and the sources' moves add in quadrature (`point_u`).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rig.analysis.fit_search import SEARCH_POINTS, local_run, search, search_rows
from rig.analysis.metrics import goodness_of_fit
from rig.data.dataset_format import usable_u
from rig.data.dataset_reader import Dataset
from rig.physics.brdf_models import BrdfModel, get_model

WEIGHTINGS = ("uncertainty", "none")
LOSSES = ("linear", "soft_l1", "huber")
#: Rows with these flags carry no usable BRDF value.
UNUSABLE_FLAGS = ("roi_unlit", "roi_saturated")
#: A parameter this close to a bound on the unit cube is at it (a trust-region solver stops short of it).
AT_BOUND = 1e-4
#: A singular value below this fraction of the largest marks an unconstrained direction.
RCOND = 1e-9
#: A parameter whose weight in an unconstrained direction exceeds this is undetermined.
NULL_WEIGHT = 1e-3
#: Residual given to a non-finite model value, so a model's overflow steers the optimiser away.
NONFINITE_RESIDUAL = 1e12


@dataclass(frozen=True)
class ParamSpace:
    """A model's free parameters mapped onto [0, 1]^k; fixed ones are carried along."""

    free: tuple[str, ...]
    fixed: Mapping[str, float]
    lo: np.ndarray        # bounds in the mapped coordinate: log10(p) for log-scaled, p otherwise
    hi: np.ndarray
    log: np.ndarray       # bool per free parameter

    @classmethod
    def of(cls, model: BrdfModel, fixed: Mapping[str, float] | None = None) -> ParamSpace:
        fixed = dict(fixed or {})
        unknown = sorted(set(fixed) - set(model.param_names))
        if unknown:
            raise ValueError(f"{model.name} has no parameter {', '.join(unknown)}; "
                             f"its parameters: {', '.join(model.param_names)}")
        for name, value in fixed.items():
            low, high = model.bounds[name]
            if not (math.isfinite(value) and low <= value <= high):
                raise ValueError(f"fixed {name} = {value} outside its bounds [{low}, {high}]")
        free = tuple(p for p in model.param_names if p not in fixed)
        if not free:
            raise ValueError(f"every parameter of {model.name} is fixed: nothing to fit")
        log = np.array([p in model.log_scale for p in free])
        lo = np.array([model.bounds[p][0] for p in free], float)
        hi = np.array([model.bounds[p][1] for p in free], float)
        if not np.all(np.isfinite(lo) & np.isfinite(hi) & (lo < hi) & (~log | (lo > 0))):
            raise ValueError(f"{model.name}: fitting needs finite bounds low < high, low > 0 in log space, "
                             f"for {', '.join(free)}")
        lo_mapped, hi_mapped = (np.where(log, np.log10(np.where(log, b, 1.0)), b) for b in (lo, hi))
        return cls(free, fixed, lo_mapped, hi_mapped, log)

    def values(self, x: np.ndarray) -> np.ndarray:
        """Free parameter values at unit-cube point x."""
        v = self.lo + (self.hi - self.lo) * x
        return np.where(self.log, 10.0 ** v, v)

    def params(self, x: np.ndarray) -> dict[str, float]:
        return {**self.fixed, **dict(zip(self.free, map(float, self.values(x))))}

    def to_unit(self, params: Mapping[str, float]) -> np.ndarray:
        """Unit-cube point of the given free values, clipped into the box."""
        p = np.array([params[name] for name in self.free], float)
        v = np.where(self.log, np.log10(np.maximum(p, 10.0 ** self.lo)), p)
        return np.clip((v - self.lo) / (self.hi - self.lo), 0.0, 1.0)

    def jacobian_diag(self, x: np.ndarray) -> np.ndarray:
        """dp/dx per free parameter, for the delta method."""
        return (self.hi - self.lo) * np.where(self.log, self.values(x) * np.log(10.0), 1.0)


@dataclass(frozen=True)
class FitResult:
    """Outcome of one fit; `to_json()` is what `rig fit --json` writes."""

    model: str
    params: dict[str, float]
    stderr: dict[str, float]          # inf where the data do not determine the parameter; 0 when fixed
    #: Of the free parameters (fixed ones are left out), in their units; inf where undetermined.
    covariance: dict[str, dict[str, float]]
    metrics: dict[str, float]         # rmse, nrmse, ncc (Eqs. 16, 19, 20), unweighted
    chi2_dof: float | None            # weighted fits only
    n_points: int
    n_starts: int
    n_starts_at_best: int             # local starts that reached the best cost: agreement of the global stage
    converged: bool
    message: str
    nfev: int                         # model evaluations over all stages, finite differences included
    wall_s: float
    weighting: str
    loss: str
    f_scale: float | None             # robust-loss scale, in residual units
    fixed: tuple[str, ...] = ()
    at_bound: tuple[str, ...] = ()
    undetermined: tuple[str, ...] = ()
    #: Standard uncertainty of each parameter from the errors shared by the points (calibrations): apart from
    #: `stderr`, which the point-to-point scatter gives; empty when no shared u was given.
    stderr_correlated: dict[str, float] = field(default_factory=dict)

    def to_json(self) -> dict[str, Any]:
        """JSON-safe: non-finite numbers (undetermined stderr, NCC of a constant model) become null."""
        return {
            "model": self.model,
            "params": self.params,
            "stderr": {k: _finite_or_none(v) for k, v in self.stderr.items()},
            "stderr_correlated": {k: _finite_or_none(v) for k, v in self.stderr_correlated.items()},
            "covariance": {p: {q: _finite_or_none(v) for q, v in row.items()} for p, row in self.covariance.items()},
            "metrics": {k: _finite_or_none(v) for k, v in self.metrics.items()},
            "diagnostics": {
                "n_points": self.n_points, "weighting": self.weighting, "loss": self.loss,
                "f_scale": self.f_scale, "chi2_dof": self.chi2_dof, "converged": self.converged,
                "message": self.message, "n_starts": self.n_starts, "n_starts_at_best": self.n_starts_at_best,
                "nfev": self.nfev, "wall_s": self.wall_s, "fixed": list(self.fixed),
                "at_bound": list(self.at_bound), "undetermined": list(self.undetermined),
            },
        }


def _finite_or_none(v: float) -> float | None:
    return float(v) if math.isfinite(v) else None


def _rho(z2: np.ndarray, loss: str) -> np.ndarray:
    """scipy's loss functions ρ(z²), so global-stage and local costs are the same number."""
    if loss == "soft_l1":
        return 2.0 * (np.sqrt(1.0 + z2) - 1.0)
    if loss == "huber":
        return np.where(z2 <= 1.0, z2, 2.0 * np.sqrt(z2) - 1.0)
    return z2


def _cost(r: np.ndarray, loss: str, scale: float) -> float:
    return float(0.5 * scale ** 2 * np.sum(_rho((r / scale) ** 2, loss)))


def mad_scale(r: np.ndarray) -> float:
    """Robust standard deviation of residuals about zero: 1.4826 · median |r|."""
    return float(1.4826 * np.median(np.abs(r)))


def _covariance(jac: np.ndarray, variance: float) -> tuple[np.ndarray, np.ndarray]:
    """Covariance in unit-cube coordinates and the mask of undetermined parameters.

    Covariance variance·(JᵀJ)⁺ restricted to the directions the data constrain; a
    parameter with weight in an unconstrained direction gets inf in its row and column.
    """
    _, sv, vt = np.linalg.svd(jac, full_matrices=False)
    ok = sv > RCOND * sv[0] if sv[0] > 0 else np.zeros_like(sv, bool)
    undetermined = np.any(np.abs(vt[~ok]) > NULL_WEIGHT, axis=0)
    cov = (vt[ok].T / sv[ok] ** 2) @ vt[ok] * variance
    cov[undetermined, :] = np.inf
    cov[:, undetermined] = np.inf
    return cov, undetermined


def _check_inputs(wi, wo, f, u, weighting: str, loss: str) -> tuple[np.ndarray, ...]:
    if weighting not in WEIGHTINGS:
        raise ValueError(f"weighting {weighting!r}; allowed: {', '.join(WEIGHTINGS)}")
    if loss not in LOSSES:
        raise ValueError(f"loss {loss!r}; allowed: {', '.join(LOSSES)}")
    wi, wo, f = (np.asarray(a, float) for a in (wi, wo, f))
    if wi.shape != wo.shape or wi.shape != (len(f), 3):
        raise ValueError(f"wi, wo must be (N, 3) with N = len(f) = {len(f)}, got {wi.shape} and {wo.shape}")
    if not np.all(np.isfinite(f)):
        raise ValueError("measured BRDF values must be finite")
    if weighting == "none":
        return wi, wo, f, np.ones_like(f)
    if u is None:
        raise ValueError("weighting by uncertainty needs u (u_brdf_per_sr); fit unweighted instead (--unweighted)")
    u = np.asarray(u, float)
    if u.shape != f.shape or not np.all(np.isfinite(u) & (u > 0)):
        raise ValueError("uncertainties must be finite and > 0 for every point; fit unweighted instead (--unweighted)")
    return wi, wo, f, u


def fit(model_name: str, wi: np.ndarray, wo: np.ndarray, f: np.ndarray, u: np.ndarray | None = None, *,
        weighting: str = "uncertainty", loss: str = "linear", starts: int = 4,
        fixed: Mapping[str, float] | None = None, seed: int = 0,
        shared: Mapping[str, np.ndarray] | None = None) -> FitResult:
    """Fit `model_name` to f(wi, wo) (SCS unit vectors, sr⁻¹) by bounded, transformed least squares.

    weighting "uncertainty" minimises Σ((model − f)/u)², "none" the paper's Σ(model − f)².
    The `starts` best distinct optima of the global stage are refined on all points (when it worked on a
    subsample); `fixed` holds parameters at given values. `shared`: per source of an error shared by the
    points, each point's relative standard uncertainty from it (0 where it does not apply), propagated to
    `stderr_correlated` (module docstring).
    """
    t0 = time.perf_counter()
    model = get_model(model_name)
    wi, wo, f, sigma = _check_inputs(wi, wo, f, u, weighting, loss)
    space = ParamSpace.of(model, fixed)
    k, n = len(space.free), len(f)
    dof = n - k
    if dof < 1:
        raise ValueError(f"{n} points cannot determine {k} parameters")
    rng = np.random.default_rng(seed)
    nfev = 0

    def residuals(x: np.ndarray, rows: np.ndarray | slice = slice(None)) -> np.ndarray:
        nonlocal nfev
        nfev += 1
        with np.errstate(all="ignore"):
            r = (model.evaluate(wi[rows], wo[rows], **space.params(x)) - f[rows]) / sigma[rows]
        return np.where(np.isfinite(r), r, NONFINITE_RESIDUAL)

    def scale_at(x: np.ndarray, rows: np.ndarray | slice) -> float:
        """Robust-loss scale: MAD of the residuals, floored so noiseless data do not make it pure L1."""
        return max(mad_scale(residuals(x, rows)), 1e-3 * float(np.median(np.abs(f / sigma))))

    subsampled = n > SEARCH_POINTS
    sub = search_rows(f, rng) if subsampled else slice(None)
    x_typ = space.to_unit({**model.typical, **space.fixed})

    def scale_on(rows: np.ndarray | slice) -> Callable[[np.ndarray], float]:
        return (lambda x: scale_at(x, rows)) if loss != "linear" else (lambda x: 1.0)

    def cost(r: np.ndarray, scale: float) -> float:
        return _cost(r, loss, scale)

    found = search(lambda x: residuals(x, sub), cost, scale_on(sub), x_typ, rng, loss, starts, f[sub] / sigma[sub])
    # The search ranks the basins (on a subsample, to its loose tolerance); each close one is refined on
    # all points to scipy's tolerances, and the best kept
    scale = scale_on(slice(None))(found.optima[0])
    runs = [local_run(residuals, x0, loss, scale, "lsmr") for x0 in found.optima]
    best = runs[int(np.argmin([cost(r.fun, scale) for r in runs]))].x
    scale = scale_on(slice(None))(best)        # the M-estimator's scale, re-estimated at the solution
    final = local_run(residuals, best, loss, scale, "exact")
    x = final.x
    r = residuals(x)
    chi2_dof = float(np.sum(r ** 2) / dof) if weighting == "uncertainty" else None
    variance = float(np.sum(r ** 2) / dof) if loss == "linear" else mad_scale(r) ** 2
    if weighting == "uncertainty":
        variance = max(variance, 1.0)       # u are standard uncertainties: inflate only, by the Birge ratio
    cov_x, undetermined = _covariance(final.jac, variance)
    scale_p = space.jacobian_diag(x)
    with np.errstate(invalid="ignore"):          # inf · 0 off the diagonal of an undetermined parameter
        cov_p = np.where(np.isinf(cov_x), np.inf, cov_x * np.outer(scale_p, scale_p))
    se = np.sqrt(np.maximum(np.diag(cov_p), 0.0))
    params = space.params(x)
    with np.errstate(all="ignore"):
        fr = model.evaluate(wi, wo, **params)
    stderr = {p: float(se[space.free.index(p)]) if p in space.free else 0.0 for p in model.param_names}
    covariance = {p: {q: float(cov_p[space.free.index(p), space.free.index(q)]) for q in space.free}
                  for p in space.free}
    moves = [scale_p * (np.linalg.pinv(final.jac) @ (np.asarray(s_rel, float) * f / sigma))
             for s_rel in (shared or {}).values()]
    u_corr = np.sqrt(np.sum(np.square(moves), axis=0)) if moves else np.zeros(len(space.free))
    return FitResult(
        stderr_correlated={p: float(u_corr[space.free.index(p)]) if p in space.free else 0.0
                           for p in model.param_names} if shared else {},
        model=model.name, params={p: params[p] for p in model.param_names}, stderr=stderr, covariance=covariance,
        metrics=goodness_of_fit(f, fr), chi2_dof=chi2_dof, n_points=n, n_starts=found.n_runs,
        n_starts_at_best=found.n_at_best, converged=bool(final.status > 0), message=final.message, nfev=nfev,
        wall_s=time.perf_counter() - t0, weighting=weighting, loss=loss,
        f_scale=scale if loss != "linear" else None, fixed=tuple(space.fixed),
        at_bound=tuple(p for p, a, xi in zip(space.free, final.active_mask, x)
                       if a != 0 or min(xi, 1.0 - xi) < AT_BOUND),
        undetermined=tuple(p for p, u_ in zip(space.free, undetermined) if u_))


def usable_rows(dataset: Dataset, exclude_flags: tuple[str, ...] = UNUSABLE_FLAGS) -> np.ndarray:
    """Mask of rows carrying none of `exclude_flags`."""
    bad = set(exclude_flags)
    return np.array([not bad.intersection(flags) for flags in dataset.flags], bool)


def choose_weighting(u: np.ndarray, point_ids: list[str], requested: str | None) -> tuple[str, str | None]:
    """The weighting of a fit of these rows and, when it was chosen for the user, a one-line notice.

    `requested` "uncertainty" (--weighted) or "none" (--unweighted) is obeyed; "uncertainty" needs a
    usable u on every row. None (the default) lets the data decide: weighted when every row has u,
    unweighted (said in the notice) when none has, as for an imported ALTA file without #VS.
    When only some rows have u the choice is refused rather than guessed: weighting would need u
    invented for the others, and fitting unweighted would silently drop the uncertainties the lab
    measured and the χ²/dof that checks them; a mix usually means merged sources or a broken
    budget, which the user should see. ValueError names the column, the count and a row.
    """
    if requested is not None and requested not in WEIGHTINGS:
        raise ValueError(f"weighting {requested!r}; allowed: {', '.join(WEIGHTINGS)}")
    has_u = usable_u(u)
    n, n_u = len(has_u), int(np.count_nonzero(has_u))
    if requested == "none":
        return "none", None
    if n_u == n:                # every row has u (or there is no row: fit_dataset then says so)
        return "uncertainty", None
    if requested is None and n_u == 0:
        return "none", ("no row has an uncertainty (u_brdf_per_sr is 0 or missing): "
                        "fitting unweighted (the paper's RMSE; no χ²/dof)")
    example = point_ids[int(np.argmin(has_u))]
    missing = f"{n - n_u} of {n} rows have no usable u_brdf_per_sr (finite, > 0), e.g. point {example}"
    if requested == "uncertainty":
        raise ValueError(f"--weighted needs u_brdf_per_sr on every row; {missing}; fit --unweighted instead")
    raise ValueError(f"{missing}: choose --unweighted, or leave those rows out "
                     "(--exclude-flag no_uncertainty for imported ones)")


def fit_dataset(dataset: Dataset, model_name: str, *, exclude_flags: tuple[str, ...] = UNUSABLE_FLAGS,
                **kwargs: Any) -> FitResult:
    """`fit` on a dataset's achieved angles, leaving out rows with `exclude_flags`."""
    keep = usable_rows(dataset, exclude_flags)
    if not keep.any():
        raise ValueError(f"{dataset.path}: no row without the flags {', '.join(exclude_flags)}")
    wi, wo = dataset.directions()
    u, shared = point_u(dataset, keep)
    return fit(model_name, wi[keep], wo[keep], dataset["brdf_per_sr"][keep], u, shared=shared, **kwargs)


def point_u(dataset: Dataset, keep: np.ndarray) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """The u that weights a fit of the `keep` rows, and the shared errors to propagate (module docstring).

    A dataset that gives the point-to-point part on every row is weighted by it, and its calibrations are
    the shared sources: the camera's and the meter's together with the static grain's common part (every
    point; rig.physics.static_texture), the axes' zero errors
    (every point, through tan θi), each filter position's transmission (its points). Otherwise (an import,
    a dataset written before the split) the whole `u_brdf_per_sr` weights it, with nothing apart."""
    cols = dataset.columns
    if "u_brdf_point_per_sr" not in cols or not np.all(usable_u(dataset["u_brdf_point_per_sr"][keep])):
        return dataset["u_brdf_per_sr"][keep], {}
    shared = {"calibration": np.sqrt(sum(np.nan_to_num(dataset[c][keep]) ** 2 if c in cols else np.zeros(keep.sum())
                                         for c in ("u_rel_calibration", "u_rel_meter_calibration",
                                                   "u_rel_texture_static")))}
    if "u_rel_angle_zero" in cols:
        shared["axis zeros"] = np.nan_to_num(dataset["u_rel_angle_zero"][keep])
    if "filter_position" in cols and "u_rel_attenuation" in cols:
        position, u_att = dataset["filter_position"][keep], np.nan_to_num(dataset["u_rel_attenuation"][keep])
        for p in np.unique(position[np.isfinite(position) & (position > 0)]):
            shared[f"filter {int(p)}"] = np.where(position == p, u_att, 0.0)
    return dataset["u_brdf_point_per_sr"][keep], shared
