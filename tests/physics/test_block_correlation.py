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
        roi_pattern=stats.pattern, roi_pattern_quadratic=stats.quadratic, u_lobe_cd_m2=stats.u_lobe,
        lobe_weights=stats.centre_weights,
        lobe_bias_rel=stats.lobe_bias_rel)
    motors = (-30.0, 0.0, 50.0, -90.0)                  # geometry.inverse_deg(30, 0, 10, 180)
    point = PlannedPoint(f"s0-p{k}", 0, 30.0, 0.0, 10.0, 180.0, motors)
    angles = BrdfAngles(np.float64(30.0), np.float64(0.0), np.float64(10.0), np.float64(180.0))
    return Measurement(point, motors, angles, capture, (), "2026-01-01T00:00:00Z", 0.0)


def test_pooled_block_correlation_gives_the_roi_means_true_scatter():
    rng = np.random.default_rng(34)
    points = [measurement(k, L * texture(rng)) for k in range(150)]
    run = StaticTexture()                            # one sample area, one half vector: no static split
    u = np.array([math.hypot(*texture_split(m, run)[:2]) for m in points])    # the texture's (a flank's bias apart)
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
        stats = roi_statistics(np.kron(means, np.ones((10, 10))), np.zeros((70, 70)))
        pattern = stats.pattern                 # the log block means about the lobe fit's quadratic: 43 dof
        assert pattern is not None and stats.quadratic
        blocks.observe(str(k), pattern, 1.0, quadratic=True)
        correlated, independent = mean_variances(pattern, quadratic=True)
        assert independent == pytest.approx(np.sum(pattern ** 2) / 43 / 49)
    assert blocks.inflation(1.0, (7, 7)) == pytest.approx(1.0, abs=0.05)
    assert blocks.inflation(5.0, (7, 7)) == blocks.inflation(1.0, (7, 7))  # no view of that class yet: the run's
    assert BlockCorrelation().inflation(1.0, (7, 7)) is None


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


@pytest.mark.parametrize("shape", [(3, 4), (4, 3), (4, 4), (3, 5)])
def test_the_smallest_corrected_lobes_give_a_finite_variance(shape):
    """A lobe is fitted from 3 × 4 blocks on (rig.physics.footprint): its pattern, the residual of a quadratic,
    leaves the moments independent there too (the quadratic projector's moment matrix has full rank)."""
    pattern = np.random.default_rng(2).standard_normal(shape)
    correlated, independent = mean_variances(pattern, quadratic=True)
    assert math.isfinite(correlated) and math.isfinite(independent) and independent > 0


def test_weighted_sums_of_blocks_take_the_pooled_covariances():
    """Var(Σ v·blocks) in units of a block's independent variance: Σ v² for independent blocks; for blocks
    sharing an edge-neighbour covariance ρ, Σ v² + ρ vᵀK₁v, which a sign-changing v (a lobe's centre weights)
    makes smaller than the even mean's."""
    rng = np.random.default_rng(11)
    independent, correlated = BlockCorrelation(), BlockCorrelation()
    rows = cols = 7
    for k in range(400):
        white = rng.standard_normal((rows + 1, cols + 1))
        independent.observe(str(k), roi_statistics(np.kron(1 + 0.01 * white[:rows, :cols], np.ones((10, 10))),
                                                    np.zeros((70, 70))).pattern, 1.0, quadratic=True)
        shared = white[:rows, :cols] + white[1:, :cols] + white[:rows, 1:] + white[1:, 1:]  # 2 × 2 sums: ρ₁ ½, ρ₂ ¼
        correlated.observe(str(k), roi_statistics(np.kron(1 + 0.005 * shared, np.ones((10, 10))),
                                                  np.zeros((70, 70))).pattern, 1.0, quadratic=True)
    even = np.full((rows, cols), 1.0 / 49)
    alternating = np.fromfunction(lambda r, c: (-1.0) ** (r + c), (rows, cols)) / 49
    for v in (even, alternating):
        assert independent.weighted_variance(1.0, v) == pytest.approx(np.sum(v ** 2), rel=0.15)
    assert correlated.weighted_variance(1.0, even) / np.sum(even ** 2) > 3.0
    assert correlated.weighted_variance(1.0, alternating) / np.sum(alternating ** 2) < 0.5
    assert BlockCorrelation().weighted_variance(1.0, even) is None


def test_a_corrected_lobes_centre_value_takes_the_pooled_covariances_through_its_weights():
    """On a narrow lobe (σ 15 px) corrected to its centre value, the texture reaches that value through the
    centre weights (rig.physics.footprint.centre_weights), about twice what it gives the plain ROI mean; with
    the run's pooled block covariances the stated u (texture ⊕ lobe) matches the centre values' true scatter."""
    rng = np.random.default_rng(15)
    c = np.arange(ROI) + 0.5 - ROI / 2
    x, y = np.meshgrid(c, c)
    run, errors, u, u_texture = StaticTexture(), [], [], []
    for k in range(150):
        dx, dy = rng.uniform(-15.0, 15.0, 2)
        lobe = np.exp(-((x - dx) ** 2 + (y - dy) ** 2) / (2 * 15.0 ** 2))
        m = measurement(k, L * lobe * texture(rng))
        own_texture, _, own_lobe = texture_split(m, run)
        if k >= MIN_VIEWS and m.capture.lobe_weights is not None:
            errors.append(m.capture.luminance_cd_m2 / (L * math.exp(-(dx * dx + dy * dy) / (2 * 15.0 ** 2))) - 1)
            u.append(math.hypot(own_texture, own_lobe) / m.capture.luminance_cd_m2)
            u_texture.append(own_texture / m.capture.luminance_cd_m2)
    errors, u = np.array(errors), np.array(u)
    assert errors.size > 100
    assert np.sqrt(np.mean(errors ** 2)) / np.sqrt(np.mean(u ** 2)) == pytest.approx(1.0, abs=0.15)
    assert np.sqrt(np.mean(errors ** 2)) > 1.5 * np.sqrt(np.mean(np.square(u_texture)))
