"""The peak of a 2-D scan from a quadratic in its log (rig.physics.peak_fit), against closed-form lobes."""

import numpy as np
import pytest

from rig.physics.peak_fit import PeakNotFound, fit_log_peak

STEP = 0.2
TICKS = STEP * np.arange(-2, 3)
X, Y = (a.ravel() for a in np.meshgrid(TICKS, TICKS))


def gaussian(x0, y0, sx, sy, rho=0.0, peak=100.0):
    """A 2-D Gaussian lobe: its log is exactly quadratic, so the fit must return its centre and width."""
    dx, dy = (X - x0) / sx, (Y - y0) / sy
    return peak * np.exp(-(dx * dx - 2 * rho * dx * dy + dy * dy) / (2 * (1 - rho * rho)))


@pytest.mark.parametrize("x0, y0, sx, sy, rho", [(0.0, 0.0, 1.0, 1.0, 0.0), (0.031, -0.017, 0.5, 0.9, 0.0),
                                                  (-0.12, 0.25, 0.33, 0.4, 0.3)])
def test_a_gaussian_lobe_is_located_exactly(x0, y0, sx, sy, rho):
    peak = fit_log_peak(X, Y, gaussian(x0, y0, sx, sy, rho))
    assert peak.x0 == pytest.approx(x0, abs=1e-9)
    assert peak.y0 == pytest.approx(y0, abs=1e-9)
    assert peak.u_x0 == pytest.approx(0.0, abs=1e-9)           # an exact quadratic leaves no residual
    if rho == 0.0:
        assert peak.width == pytest.approx(min(sx, sy), rel=1e-9)


def test_a_phong_lobe_is_located_to_a_small_fraction_of_the_step():
    """cos^n is not a Gaussian beyond second order; its quartic terms are symmetric and do not move the peak."""
    n, x0, y0 = 3000.0, 0.013, -0.021
    alpha = np.radians(np.hypot(X - x0, Y - y0))
    peak = fit_log_peak(X, Y, np.cos(alpha) ** n + 1e-3)
    assert abs(peak.x0 - x0) < 2e-4 and abs(peak.y0 - y0) < 2e-4
    assert peak.width == pytest.approx(np.degrees(1 / np.sqrt(n)), rel=0.05)


def test_the_stated_uncertainty_covers_the_error_of_noisy_scans():
    rng = np.random.default_rng(7)
    z = []
    for _ in range(400):
        noisy = gaussian(0.05, -0.03, 0.6, 0.6) * np.exp(rng.normal(0, 0.01, X.size))
        p = fit_log_peak(X, Y, noisy)
        z += [(p.x0 - 0.05) / p.u_x0, (p.y0 + 0.03) / p.u_y0]
    z = np.asarray(z)
    assert 0.8 < np.std(z) < 1.25                # residual-based u: a t-distribution with 19 dof
    assert 0.92 < np.mean(np.abs(z) <= 2) < 0.98


@pytest.mark.parametrize("values, what", [
    (np.full(X.size, 5.0), "no maximum"),                                  # flat: a diffuse sample
    (np.exp(0.5 * X**2 - 0.5 * Y**2), "no maximum"),                       # a saddle
    (gaussian(1.5, 0.0, 0.5, 0.5), "outside the scan"),                    # peak beyond the grid
])
def test_no_peak_in_the_scan_is_refused(values, what):
    with pytest.raises(PeakNotFound, match=what):
        fit_log_peak(X, Y, values)


def test_bad_input_is_refused():
    with pytest.raises(ValueError, match="at least 7"):
        fit_log_peak(X[:5], Y[:5], np.ones(5))
    with pytest.raises(ValueError, match="positive"):
        fit_log_peak(X, Y, np.where(X > 0, 1.0, 0.0))


def test_a_drift_during_the_scan_is_told_from_the_lobe_by_a_second_visit_of_the_centre():
    """The source loses 1 % over the scan (serpentine, then the centre again): without the times the peak
    moves along the scan's slow axis; with them it is where it is."""
    order = np.argsort(Y * 10 + np.where(np.round(Y / STEP) % 2 == 0, X, -X), kind="stable")
    x, y = np.r_[0.0, X[order], 0.0], np.r_[0.0, Y[order], 0.0]
    t = np.arange(x.size, dtype=float)
    lobe = 100.0 * np.exp(-((x - 0.02) ** 2 + (y + 0.01) ** 2) / (2 * 0.5 ** 2))
    values = lobe * np.exp(-0.01 * t / t[-1])                # linear in ln value, as the fit assumes
    blind, told = fit_log_peak(x, y, values), fit_log_peak(x, y, values, t)
    assert abs(blind.y0 + 0.01) > 0.002                       # the drift looks like a slope along y
    assert told.x0 == pytest.approx(0.02, abs=1e-9) and told.y0 == pytest.approx(-0.01, abs=1e-9)
