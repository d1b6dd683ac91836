"""The ROI's texture u where its blocks correlate (issue 34): a grain about a block wide makes neighbouring block
means share it, and the ROI's own u (the spread of its block means, edge neighbours' covariance from the same
blocks) falls short; pooled over the run's views by the method of moments (rig.physics.block_correlation) it
matches the ROI mean's true scatter, computed exactly for a smoothed Gaussian texture."""

import math

import numpy as np
import pytest
from scipy.ndimage import gaussian_filter

from rig.acquisition.capture import PointCapture
from rig.acquisition.rows import Measurement, texture_split
from rig.core.values import Window
from rig.physics.block_correlation import MIN_VIEWS, BlockCorrelation, mean_variances
from rig.physics.geometry import BrdfAngles
from rig.physics.roi import roi_statistics
from rig.physics.static_texture import StaticTexture
from rig.planning.points import PlannedPoint

ROI, PAD, GRAIN_PX, CONTRAST, L = 70, 24, 3.0, 0.03, 100.0


def texture(rng: np.random.Generator) -> np.ndarray:
    """A stationary texture of unit mean whose grain (Gaussian, σ = GRAIN_PX) correlates neighbouring 10 px blocks."""
    field = gaussian_filter(rng.standard_normal((ROI + 2 * PAD,) * 2), GRAIN_PX)[PAD:-PAD, PAD:-PAD]
    return 1.0 + CONTRAST * field / field_std()


def field_std() -> float:
    """Standard deviation of a pixel of the smoothed white noise (unit variance): √Σ kernel²."""
    impulse = np.zeros((2 * PAD + 1,) * 2)
    impulse[PAD, PAD] = 1.0
    return float(np.sqrt(np.sum(gaussian_filter(impulse, GRAIN_PX) ** 2)))


def true_u_mean() -> float:
    """The exact standard deviation of the ROI mean of `texture`: the white noise weighted by the ROI's
    indicator convolved with the kernel, √Σw² / N pixels, in units of L."""
    box = np.zeros((ROI + 2 * PAD,) * 2)
    box[PAD:-PAD, PAD:-PAD] = 1.0
    w = gaussian_filter(box, GRAIN_PX, mode="constant")
    return L * CONTRAST / field_std() * float(np.sqrt(np.sum(w ** 2))) / ROI ** 2


def measurement(k: int, image: np.ndarray) -> Measurement:
    """Point k: a view 10° off the normal whose ROI is `image` (noise-free)."""
    stats = roi_statistics(image, np.zeros_like(image))
    capture = PointCapture(
        luminance_cd_m2=stats.mean, u_luminance_cd_m2=stats.u_mean, roi_std_cd_m2=stats.std, exposures_s=(0.01,),
        saturated_fraction=0.0, flags=(), image_cd_m2=None, roi_window=Window(0, 0, ROI, ROI), n_frames=1,
        u_noise_cd_m2=0.0, u_dark_cd_m2=0.0, u_texture_cd_m2=stats.u_texture, capture_time_s=0.01, n_darks=1,
        roi_pattern=stats.pattern)
    motors = (-30.0, 0.0, 50.0, -90.0)                  # geometry.inverse_deg(30, 0, 10, 180)
    point = PlannedPoint(f"s0-p{k}", 0, 30.0, 0.0, 10.0, 180.0, motors)
    angles = BrdfAngles(np.float64(30.0), np.float64(0.0), np.float64(10.0), np.float64(180.0))
    return Measurement(point, motors, angles, capture, (), "2026-01-01T00:00:00Z", 0.0)


def test_pooled_block_correlation_gives_the_roi_means_true_scatter():
    rng = np.random.default_rng(34)
    points = [measurement(k, L * texture(rng)) for k in range(150)]
    run = StaticTexture()                            # one sample area, one half vector: no static split
    u = np.array([math.hypot(*texture_split(m, run)) for m in points])
    own = np.array([m.capture.u_texture_cd_m2 for m in points])
    truth = true_u_mean()
    assert np.sqrt(np.mean(own ** 2)) / truth < 0.88             # the ROI's own u: short by a sixth
    assert np.sqrt(np.mean(u[MIN_VIEWS:] ** 2)) / truth == pytest.approx(1.0, abs=0.05)
    np.testing.assert_allclose(u[:MIN_VIEWS - 1], own[:MIN_VIEWS - 1])   # too few views yet: the ROI's own


def test_independent_blocks_are_not_inflated():
    rng = np.random.default_rng(7)
    blocks = BlockCorrelation()
    for k in range(200):
        means = 1.0 + 0.01 * rng.standard_normal((7, 7))
        pattern = roi_statistics(np.kron(means, np.ones((10, 10))), np.zeros((70, 70))).pattern
        blocks.observe(str(k), pattern, 1.0)
        correlated, independent = mean_variances(pattern)
        assert independent == pytest.approx(np.sum(pattern ** 2) / 46 / 49)
    assert blocks.inflation(1.0) == pytest.approx(1.0, abs=0.05)
    assert blocks.inflation(5.0) == blocks.inflation(1.0)         # no view of that class yet: the run's
    assert BlockCorrelation().inflation(1.0) is None


@pytest.mark.parametrize("shape", [(2, 2), (2, 5), (3, 2), (3, 3)])
def test_the_smallest_rois_give_a_finite_variance(shape):
    """`capture.roi_px` may be as small as 20 px (2 × 2 blocks): a plane leaves too few residuals there to tell
    the neighbours' covariance from the variance (the moment matrix is singular, and a campaign with roi_px 20
    failed with "Singular matrix"), so the pattern counts as independent blocks; from 3 × 3 on both are estimated."""
    pattern = np.random.default_rng(1).standard_normal(shape)
    pattern -= pattern.mean()
    correlated, independent = mean_variances(pattern)
    assert math.isfinite(correlated) and math.isfinite(independent) and independent > 0
    if min(shape) < 3:
        assert correlated == pytest.approx(independent, rel=1e-12)
