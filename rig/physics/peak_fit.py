"""Where a peak lies on a 2-D scan: a quadratic fitted to the log of the values (pure numpy).

Near its maximum a smooth, positive lobe is a Gaussian to second order, so its logarithm is a
quadratic, ln L = c + gᵀx + ½ xᵀHx, whose maximum is at x* = -H⁻¹g. A least-squares fit over a
small grid around the nominal peak gives x* with an uncertainty from the fit's covariance (the
residual scatter, which holds the texture and noise of the scan, scaled by the design's leverage)
propagated to first order. rig.acquisition.alignment uses it to find the specular peak of a
glossy sample, the reference a goniometer's arm is aligned on.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: The least drop (in ln value) of the fitted lobe from its peak to the edge of the scan, along its wider axis,
#: for the scan to count as having a peak: 0.5 %, and at least 3× the residual scatter of the fit.
MIN_DROP_LN = 0.005
DROP_SIGMAS = 3.0


class PeakNotFound(ValueError):
    """The scan shows no maximum inside it (flat, saddle-shaped, or peaking beyond the grid)."""


@dataclass(frozen=True)
class LogPeak:
    """The fitted maximum of a 2-D scan, in the scan's coordinates (degrees, say)."""

    x0: float
    y0: float
    u_x0: float                   # standard uncertainties from the fit's covariance
    u_y0: float
    #: Width of the lobe along its narrower principal axis: 1/√(-λ) for the Hessian's eigenvalue λ of
    #: largest magnitude (the σ of the equivalent Gaussian), in the scan's units.
    width: float
    #: ln(max/min) of the scanned values: how much the lobe drops across the scan.
    contrast_ln: float


def fit_log_peak(x: np.ndarray, y: np.ndarray, values: np.ndarray, time_s: np.ndarray | None = None) -> LogPeak:
    """The maximum of positive `values` scanned at (x, y): at least 7 points not all on a line.

    `time_s`: when each value was taken. A source that drifts during the scan tilts the lobe along the
    scan's order and so moves the fitted peak; with the times, a drift linear in time (in ln value) is
    fitted too, which the scan must make identifiable by visiting one point twice, early and late.

    Raises PeakNotFound when the fitted quadratic has no clear maximum (it does not drop, along both
    principal axes, by MIN_DROP_LN and DROP_SIGMAS× the fit's scatter from its top to the scan's edge)
    or when the maximum lies outside the scanned box: the peak is elsewhere, or there is none.
    """
    x, y, values = (np.asarray(a, float).ravel() for a in (x, y, values))
    if not (x.size == y.size == values.size) or x.size < 7:
        raise ValueError(f"need at least 7 scan points with x, y and a value each, got {x.size}")
    if time_s is not None and np.asarray(time_s).size != x.size:
        raise ValueError(f"need a time for each of the {x.size} scan points")
    if not np.all(np.isfinite(values) & (values > 0)):
        raise ValueError("scan values must be positive and finite")
    log_v = np.log(values)
    columns = [np.ones_like(x), x, y, x * x, x * y, y * y]
    if time_s is not None:
        t = np.asarray(time_s, float).ravel()
        columns.append((t - t.mean()) / max(float(np.ptp(t)), 1e-12))     # drift over the scan, ln value
    design = np.column_stack(columns)
    coef, *_ = np.linalg.lstsq(design, log_v, rcond=None)
    _, gx, gy, a, b, c = coef[:6]
    hessian = np.array([[2 * a, b], [b, 2 * c]])
    eig = np.linalg.eigvalsh(hessian)
    dof = x.size - design.shape[1]
    residual = log_v - design @ coef
    s2 = float(residual @ residual) / dof if dof > 0 else 0.0
    reach = 0.5 * min(np.ptp(x), np.ptp(y))
    drop = -0.5 * eig[1] * reach**2          # along the wider axis (the eigenvalue nearer zero)
    if not drop > max(MIN_DROP_LN, DROP_SIGMAS * np.sqrt(s2)):
        raise PeakNotFound(f"the scan has no maximum (the fitted ln value drops {drop:.3g} from its top to the "
                           f"scan's edge along its flatter axis; residual scatter {np.sqrt(s2):.2g})")
    peak = -np.linalg.solve(hessian, np.array([gx, gy]))
    if not (x.min() <= peak[0] <= x.max() and y.min() <= peak[1] <= y.max()):
        raise PeakNotFound(f"the fitted maximum ({peak[0]:.3g}, {peak[1]:.3g}) lies outside the scan "
                           f"[{x.min():.3g}, {x.max():.3g}] × [{y.min():.3g}, {y.max():.3g}]")
    cov = s2 * np.linalg.pinv(design.T @ design)[:6, :6]
    jac = _peak_jacobian(hessian, peak)
    cov_peak = jac @ cov @ jac.T
    return LogPeak(x0=float(peak[0]), y0=float(peak[1]), u_x0=float(np.sqrt(max(cov_peak[0, 0], 0.0))),
                   u_y0=float(np.sqrt(max(cov_peak[1, 1], 0.0))), width=float(1.0 / np.sqrt(-eig[0])),
                   contrast_ln=float(log_v.max() - log_v.min()))


def _peak_jacobian(hessian: np.ndarray, peak: np.ndarray) -> np.ndarray:
    """∂x*/∂(c, gx, gy, a, b, c₂) for x* = -H⁻¹g with H = [[2a, b], [b, 2c₂]]: dx* = -H⁻¹(dg + dH·x*)."""
    h_inv = np.linalg.inv(hessian)
    px, py = peak
    d_hx = [np.zeros(2), np.array([1.0, 0.0]), np.array([0.0, 1.0]),       # c, gx, gy: dg
            np.array([2 * px, 0.0]), np.array([py, px]), np.array([0.0, 2 * py])]   # a, b, c₂: dH·x*
    return -h_inv @ np.column_stack(d_hx)
