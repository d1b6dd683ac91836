"""The interpolant checked on incidences it was not given: leave one incidence out (`rig predict`'s default).

Each measured incidence between the first and the last is left out in turn and predicted from the others at its
measured views (rig.analysis.predict.MeasuredDomain over the remaining incidences: the same interpolant, with
twice the spacing there). Two things follow, per dataset:

- **how to interpolate between incidences**: at views aligned on the lobes (`lobe_aligned`: the retroreflective
  and specular peaks move with θi) or at fixed (θo, Δφ); the one with the smaller 95th percentile of the
  held-out |error| in ln f is used (the statistic the validation scores, docs/sampling.md), and `rig predict` says
  which and by how much. Not the RMS: a handful of views at a sharp peak (a tape's retroreflection at θi 80–85°,
  one or two of ~1500 views off by ln 2–10 whichever way it is interpolated) decide an RMS alone, and on a drawn
  MRM tape the RMS chose fixed views where the lobe-aligned ones were better on 95 % of the held-out views (median
  0.027 against 0.029, p95 0.32 against 0.51): its in-hull retroreflection error went from 0.06 to 0.19;
- **how far to trust its between-incidence u**: the held-out errors against the u the interpolant stated for
  them; where more than 5 % exceed 2u, the between-incidence terms are scaled up by the factor that brings the
  95th percentile of |error|/u to 2 (never down: a held-out incidence has twice the spacing, and an estimate
  that covers there is kept as it is).

With fewer than three incidences nothing can be left out: the lobe-aligned interpolant, unscaled.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.analysis.predict import InterpolatingPredictor, MeasuredDomain, measured_domain
from rig.data.dataset_reader import Dataset

#: The k of the coverage the between-incidence u is calibrated to, and the share of held-out views it must cover.
COVERAGE_K = 2.0
COVERAGE_SHARE = 0.95


@dataclass(frozen=True)
class HeldOut:
    """Held-out views of left-out incidences: |Δ ln f| and the u_rel the interpolant stated for them."""

    error: np.ndarray
    u_rel: np.ndarray

    @property
    def rms(self) -> float:
        return float(np.sqrt(np.mean(self.error ** 2))) if self.error.size else float("nan")

    @property
    def p95(self) -> float:
        """The 95th percentile of |Δ ln f|: what decides how to interpolate (module docstring)."""
        return float(np.quantile(self.error, COVERAGE_SHARE)) if self.error.size else float("nan")

    @property
    def u_scale(self) -> float:
        """The factor (≥ 1) on u that makes COVERAGE_SHARE of the held-out views fall within COVERAGE_K·u."""
        if not self.error.size:
            return 1.0
        ratio = self.error / np.maximum(self.u_rel, 1e-12)
        return max(1.0, float(np.quantile(ratio, COVERAGE_SHARE)) / COVERAGE_K)


def held_out(domain: MeasuredDomain, aligned: bool) -> HeldOut:
    """Each inner incidence predicted at its measured views (those above the plane) from the others."""
    errors, u = [], []
    for k in range(1, len(domain.incidences) - 1):
        others = MeasuredDomain(domain.incidences[:k] + domain.incidences[k + 1:], aligned=aligned)
        inc = domain.incidences[k]
        views = inc.mesh.points[inc.mesh.points[:, 1] >= 0]
        log_f = inc.log_f[inc.mesh.points[:, 1] >= 0]
        predicted, u_rel, _ = others.evaluate(np.full(len(views), inc.theta_i_deg), views)
        errors.append(np.abs(predicted - log_f))
        u.append(u_rel)
    return HeldOut(np.concatenate(errors) if errors else np.zeros(0), np.concatenate(u) if u else np.zeros(0))


def calibrate(domain: MeasuredDomain) -> dict[bool, HeldOut]:
    """Set the domain's alignment and between-incidence u scale from its held-out incidences (module docstring);
    the held-out checks of both alignments. Fewer than three incidences: left as they are (nothing to leave out).
    Also what the adaptive sampler's guide uses (rig.analysis.adaptive)."""
    if len(domain.incidences) < 3:
        return {}
    checks = {aligned: held_out(domain, aligned) for aligned in (True, False)}
    domain.aligned = checks[True].p95 <= checks[False].p95
    domain.theta_u_scale = checks[domain.aligned].u_scale
    return checks


def interpolating_predictor(ds: Dataset) -> InterpolatingPredictor:
    """The interpolant of `ds`, its alignment and between-incidence u chosen on held-out incidences (module
    docstring), with a method text that says so."""
    domain = measured_domain(ds)
    if len(domain.incidences) < 3:
        return InterpolatingPredictor(domain)
    checks = calibrate(domain)
    aligned, scale = domain.aligned, domain.theta_u_scale
    chosen = checks[aligned]
    return InterpolatingPredictor(domain, (
        "interpolate: piecewise-linear in ln f over each incidence's views, linear in θi between them at "
        f"{'lobe-aligned' if aligned else 'fixed'} views (leave-one-incidence-out error in ln f, 95th percentile "
        f"{chosen.p95:.3g} against {checks[not aligned].p95:.3g} at {'fixed' if aligned else 'lobe-aligned'} "
        f"views; between-incidence u ×{scale:.2g} from {chosen.error.size} held-out views)"))
