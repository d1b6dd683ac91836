"""Angular footprint and lobe-curvature fit (rig.physics.footprint) against closed-form cases."""

import math

import numpy as np
import pytest

from rig.core.values import Window
from rig.physics.footprint import RESOLVED_Z, fit_lobe, view_footprint_deg
from rig.physics.optics import CameraOptics
from rig.physics.roi import block_means, point_flags, roi_statistics

OPTICS = CameraOptics(width_px=1390, height_px=1040, pixel_pitch_m=6.45e-6, focal_length_m=0.05, distance_m=1.54)
ROI_PX = 70


def gaussian_lobe(sigma_px: float, offset_px: tuple[float, float] = (0.0, 0.0), size: int = ROI_PX) -> np.ndarray:
    """exp(−|x − x0|²/(2σ²)) on pixel centres, x measured from the ROI centre: exactly quadratic in log."""
    c = np.arange(size) + 0.5 - size / 2
    x, y = np.meshgrid(c, c)
    return np.exp(-((x - offset_px[0]) ** 2 + (y - offset_px[1]) ** 2) / (2 * sigma_px ** 2))


def test_footprint_is_the_angle_from_the_roi_centre_to_its_corner():
    roi = Window.centred(OPTICS.width_px, OPTICS.height_px, ROI_PX, ROI_PX)
    half_diagonal_m = ROI_PX / 2 * math.sqrt(2) * OPTICS.pixel_pitch_m
    assert view_footprint_deg(OPTICS, roi) == pytest.approx(math.degrees(math.atan(half_diagonal_m / 0.05)),
                                                            rel=1e-9)


def test_fit_of_a_gaussian_lobe_gives_its_bias_and_width():
    sigma_px = 60.0
    for offset in ((0.0, 0.0), (90.0, -30.0)):                      # at the peak and on a flank
        image = gaussian_lobe(sigma_px, offset)
        fit = fit_lobe(block_means(image), 10, image.shape)
        centre_value = math.exp(-(offset[0] ** 2 + offset[1] ** 2) / (2 * sigma_px ** 2))
        assert fit.bias_rel == pytest.approx(image.mean() / centre_value - 1, abs=2e-3)
        assert fit.width_rel == pytest.approx(sigma_px / (ROI_PX / math.sqrt(2)), rel=0.02)
        assert fit.resolved and not fit.narrow
        half_diagonal = ROI_PX / math.sqrt(2)                           # |∇ ln f| = |x0|/σ² per px
        assert fit.slope_rel == pytest.approx(math.hypot(*offset) / sigma_px ** 2 * half_diagonal, abs=0.01)
    assert fit.bias_rel > 0.02                                       # a flank's mean is high (convex in log)


def test_peak_mean_is_low_and_corrected_to_the_centre_value():
    image = 400.0 * gaussian_lobe(20.0)
    stats = roi_statistics(image, np.full(image.shape, 1e-6))
    assert image.mean() < 0.9 * 400.0
    assert stats.mean == pytest.approx(400.0, rel=0.01)
    assert stats.u_lobe > 0 and stats.lobe_bias_rel < -0.1
    assert stats.lobe.narrow                                         # σ 20 px < half-diagonal 49.5 px
    assert "narrow_lobe" in point_flags(stats, min_snr=3.0, saturated=False)


def test_flat_noisy_roi_has_no_resolved_lobe():
    rng = np.random.default_rng(7)
    resolved = curved = 0
    for _ in range(200):
        image = 100.0 * rng.lognormal(0.0, 0.05, size=(ROI_PX, ROI_PX))
        fit = fit_lobe(block_means(image), 10, image.shape)
        assert abs(fit.bias_rel) < 5 * fit.u_bias_rel
        resolved += fit.resolved
        curved += fit.curved
        stats = roi_statistics(image, np.full(image.shape, 1.0))
        if not fit.resolved:                                         # the mean is left as it is
            assert stats.mean == image.mean() and stats.lobe_bias_rel == 0
            assert stats.u_lobe == (abs(fit.bias_rel) * stats.mean if fit.curved else 0.0)
            assert "narrow_lobe" not in point_flags(stats, 3.0, False)
    assert resolved <= 4                                             # |z| ≥ 3: 0.3 % for a normal law
    assert curved <= 5                                               # −3 < z ≤ −2.5: 0.5 %


def test_bias_uncertainty_is_honest_on_white_texture():
    rng = np.random.default_rng(3)
    z = []
    for _ in range(300):
        fit = fit_lobe(block_means(rng.lognormal(0.0, 0.05, size=(ROI_PX, ROI_PX))), 10, (ROI_PX, ROI_PX))
        z.append(fit.bias_rel / fit.u_bias_rel)
    assert 0.8 < np.std(z) < 1.25 and RESOLVED_Z > 2


def test_unfittable_rois_give_no_lobe():
    assert not fit_lobe(np.ones((2, 7)), 10, (20, 70)).resolved
    dark = np.ones((7, 7))
    dark[3, 3] = 0.0
    assert fit_lobe(dark, 10, (70, 70)).bias_rel == 0.0


def _corrected_errors(sigma_px: float, seed: int, trials: int = 300) -> tuple[np.ndarray, np.ndarray]:
    """Relative errors of the lobe-corrected centre value and their stated u (texture ⊕ lobe correction), for a
    Gaussian lobe at random offsets under a texture of independent 2 % blocks (its truth: the lobe's centre value)."""
    rng = np.random.default_rng(seed)
    errors, u = [], []
    for _ in range(trials):
        offset = rng.uniform(-1.5, 1.5, 2) * min(sigma_px, ROI_PX / 2)
        lobe = gaussian_lobe(sigma_px, tuple(offset))
        centre = math.exp(-(offset @ offset) / (2 * sigma_px ** 2))
        blocks = np.exp(rng.normal(0.0, 0.02, (7, 7)))
        stats = roi_statistics(100.0 * lobe * np.kron(blocks, np.ones((10, 10))), np.full(lobe.shape, 1e-6))
        if stats.corrected:
            errors.append(stats.mean / (100.0 * centre) - 1)
            u.append(math.hypot(stats.u_mean, stats.u_lobe) / stats.mean)
    return np.array(errors), np.array(u)


@pytest.mark.parametrize("sigma_px", [15.0, 35.0, 70.0])
def test_corrected_centre_value_u_is_honest_from_narrow_to_broad_lobes(sigma_px):
    """The ROI mean's texture error and the bias's move together (footprint.centre_weights): counted apart, a
    lobe narrower than the footprint had twice its u; and block means flattened without the within-block excess
    kept several per cent of lobe as texture. z = error / u has std ≈ 1 at every width."""
    errors, u = _corrected_errors(sigma_px, seed=int(sigma_px))
    assert errors.size > 200
    assert 0.85 < np.std(errors / u) < 1.2
    assert np.sqrt(np.mean(errors ** 2)) > 1.5 * 0.02 / 7      # the centre costs more than the plain mean would


def test_centre_weights_are_the_corrected_values_linear_response():
    """A small texture δ (in log, per block) moves the corrected centre value by L·δ, L = centre_weights;
    L sums to 1 (a uniform gain moves the value by itself); for a flat ROI L is the quadratic's intercept row."""
    image = 100.0 * gaussian_lobe(25.0, (20.0, -10.0))
    base = roi_statistics(image, np.full(image.shape, 1e-6))
    weights = base.centre_weights
    assert weights is not None and float(np.sum(weights)) == pytest.approx(1.0, abs=1e-9)
    delta = 1e-4 * np.random.default_rng(5).standard_normal((7, 7))
    moved = roi_statistics(image * np.kron(np.exp(delta), np.ones((10, 10))), np.full(image.shape, 1e-6))
    assert moved.mean / base.mean - 1 == pytest.approx(float(np.sum(weights * delta)), abs=2e-6)
    flat = fit_lobe(np.ones((7, 7)) + 0.0, 10, (ROI_PX, ROI_PX))
    assert flat.centre_weights is not None
    assert float(np.sum(flat.centre_weights ** 2)) * 49 == pytest.approx(3.667, abs=0.01)
