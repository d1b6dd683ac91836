"""Closed-form cases of the EMVA 1288 calibration functions (rig.physics.camera_calibration)."""

import math

import numpy as np
import pytest

from rig.config.rigfile import CameraConfig, SimulationConfig
from rig.core.values import SensorInfo, Window
from rig.physics import camera_calibration as cc
from rig.simulators.sensor import SensorModel, convert_nonlinear, natural_vignetting

RNG = np.random.default_rng(7)


def test_stack_stats_and_spatial_variance_separate_temporal_from_fixed_pattern():
    pattern = 3.0 * RNG.standard_normal((200, 300))
    stack = 100 + pattern + 2.0 * RNG.standard_normal((8, 200, 300))
    stats = cc.stack_stats(stack)
    assert stats.temporal_var_dn2 == pytest.approx(4.0, rel=0.01)
    assert stats.var_of_mean_dn2 == pytest.approx(4.0 / 8, rel=0.01)
    # the mean image holds the pattern (9) plus 4/8 of temporal noise; the correction removes the latter
    assert cc.spatial_variance(stats) == pytest.approx(pattern.var(ddof=1), rel=0.005)
    with pytest.raises(ValueError, match="two frames"):
        cc.stack_stats(stack[:1])


def test_dark_level_dsnu_and_temporal_noise():
    dark = 64 + 0.5 * RNG.standard_normal((100, 100))
    level = cc.dark_level(cc.stack_stats(dark + 1.5 * RNG.standard_normal((16, 100, 100))), 0.1)
    assert level.mean_dn == pytest.approx(64, abs=0.01)
    assert level.dsnu_dn == pytest.approx(dark.std(), rel=0.02)
    assert level.temporal_std_dn == pytest.approx(1.5, rel=0.01)
    uniform = cc.dark_level(cc.stack_stats(64 + 1.5 * RNG.standard_normal((4, 100, 100))), 0.1)
    assert uniform.dsnu_dn < 0.15     # no fixed pattern: what is left is the sampling noise of a variance


def test_photon_transfer_recovers_gain_and_dark_noise_exactly():
    k, sigma_d = 0.25, 7.0
    signal = np.linspace(100, 4000, 10)
    dark_var = (k * sigma_d) ** 2 + 1 / 12
    ptc = cc.photon_transfer(signal, k * signal, dark_var, saturation_dn=4000)
    assert ptc.gain_dn_per_e == pytest.approx(k, rel=1e-12)
    assert ptc.u_gain_dn_per_e == pytest.approx(0, abs=1e-12)
    assert ptc.read_noise_e == pytest.approx(sigma_d, rel=1e-12)
    # above 70 % of saturation the variance bends (full well): ignored
    bent = np.where(signal > 2800, 0.5 * k * signal, k * signal)
    assert cc.photon_transfer(signal, bent, dark_var, 4000).gain_dn_per_e == pytest.approx(k, rel=1e-12)


def test_linearity_of_a_linear_and_of_a_quadratic_response():
    t = np.linspace(0.01, 0.1, 10)
    lin = cc.linearity(t, 50 + 30000 * t, np.full(10, 0.5), saturation_dn=4000)
    assert lin.le_percent == pytest.approx(0, abs=1e-9)
    assert lin.slope_dn_s == pytest.approx(30000) and lin.offset_dn == pytest.approx(50)
    assert lin.u_le_percent == pytest.approx(100 * cc.expected_half_range(10) * np.sqrt(np.mean(
        (0.5 / (50 + 30000 * t)) ** 2)))
    # y = a t²: the weighted straight line leaves known relative deviations; LE is half their range
    t = np.linspace(0.03, 0.1, 10)
    y = 3.0e5 * t ** 2
    quad = cc.linearity(t, y, np.ones(10), saturation_dn=3200)
    offset, slope = np.polynomial.polynomial.polyfit(t, y, 1, w=1 / y)
    delta = (y - offset - slope * t) / (offset + slope * t)
    assert quad.le_percent == pytest.approx(50 * (delta.max() - delta.min()), rel=1e-9)
    assert quad.le_percent > 5
    with pytest.raises(ValueError, match="three exposures"):
        cc.linearity(t, 50 + 30000 * t, np.ones(10), saturation_dn=1e6)       # all below 5 %


def test_expected_half_range_closed_forms():
    assert cc.expected_half_range(2) == pytest.approx(1 / math.sqrt(math.pi), rel=1e-9)
    assert cc.expected_half_range(3) == pytest.approx(1.5 / math.sqrt(math.pi), rel=1e-9)   # E[R₃] = 3/√π
    assert cc.expected_half_range(1) == pytest.approx(0, abs=1e-12)


def _stats(image, var=0.0, frames=4):
    return cc.StackStats(np.asarray(image, float), var, frames)


def test_flat_field_splits_a_polynomial_falloff_from_prnu():
    h, w = 120, 160
    x, y = np.meshgrid((np.arange(w) + 0.5) / w * 2 - 1, (np.arange(h) + 0.5) / h * 2 - 1)
    falloff = 1 - 0.04 * (x ** 2 + y ** 2) + 0.01 * x ** 2 * y ** 2
    prnu = 0.01 * RNG.standard_normal((h, w))
    centre = Window.centred(w, h, 20, 20)
    flat = cc.flat_field(_stats(64 + 2000 * falloff * (1 + prnu), var=0.0), _stats(np.full((h, w), 64.0)), centre)
    rows, cols = Window(0, 0, w, h).inner(centre)
    assert flat.relative[rows, cols].mean() == pytest.approx(1, abs=1e-6)
    assert flat.prnu_rel == pytest.approx(prnu.std(), rel=0.01)
    # the corner value of the fitted fall-off, relative to the centre's level
    level = (falloff * (1 + prnu))[rows, cols].mean()
    assert flat.corner_rel == pytest.approx((1 - 0.08 + 0.01) / level, abs=3 * flat.u_corner_rel)
    assert 0 < flat.u_corner_rel < 1e-3
    smooth = cc.falloff_map(flat.coefficients, h, w, flat.degree)
    np.testing.assert_allclose(smooth * level, falloff, atol=3e-3)
    # temporal noise in the averaged flat is taken out of the PRNU
    noisy = _stats(64 + 2000 * falloff * (1 + prnu) + 20 * RNG.standard_normal((h, w)), var=400.0 * 4, frames=4)
    assert cc.flat_field(noisy, _stats(np.full((h, w), 64.0)), centre).prnu_rel == pytest.approx(prnu.std(), rel=0.02)
    with pytest.raises(ValueError, match="no brighter"):
        cc.flat_field(_stats(np.full((h, w), 64.0)), _stats(np.full((h, w), 64.0)), centre)


def test_luminance_coefficient_and_budget():
    t = np.array([0.01, 0.02, 0.04, 0.08])
    rate = 25000.0
    flat = cc.FlatField(np.ones((2, 2), np.float32), 0.01, 0, np.array([1.0]), 1.0, 0.0, 0.0, 0.0)
    k = cc.luminance_coefficient(100.0, 0.01, t, rate * t, np.full(4, 0.5), np.ones(4, bool), flat, 400,
                                 exposure_u_rel=0.002)
    assert k.cd_m2_per_dn_s == pytest.approx(100 / rate)
    weights = (t / 0.5) ** 2
    assert k.budget["noise"] == pytest.approx(1 / np.sqrt(weights.sum()) / rate)
    assert k.budget["linearity"] == pytest.approx(0, abs=1e-12)
    assert k.budget["flat_field"] == pytest.approx(0.01 / 20)
    assert k.u_rel == pytest.approx(np.sqrt(sum(v ** 2 for v in k.budget.values())))
    assert k.u_rel > np.hypot(0.01, 0.002)
    # rates that differ between exposures (a nonlinear camera) count in the budget
    factors = np.array([0.98, 0.99, 1.0, 1.01])
    bent = cc.luminance_coefficient(100.0, 0.01, t, rate * t * factors, np.full(4, 0.5), np.ones(4, bool), flat, 400)
    mean = np.sum(weights * factors) / weights.sum()          # the inverse-variance mean rate
    assert bent.cd_m2_per_dn_s == pytest.approx(100 / (rate * mean))
    assert bent.budget["linearity"] == pytest.approx(np.std(factors / mean, ddof=1))


def test_calibrated_sensor_info_gives_a_window_of_its_flat_field():
    flat = np.arange(12, dtype=float).reshape(3, 4)
    sensor = cc.CalibratedSensorInfo(4, 3, 12, 0.2, 8, 64, 0.005, 0.01, flat_field=flat)
    np.testing.assert_array_equal(sensor.flat_of(Window(1, 1, 2, 2)), [[5, 6], [9, 10]])
    assert isinstance(sensor, SensorInfo)
    assert sensor == cc.CalibratedSensorInfo(4, 3, 12, 0.2, 8, 64, 0.005, 0.01, flat_field=flat * 2)


def test_natural_vignetting_leaves_the_default_rigs_roi_alone():
    """The default rig (50 mm lens, 1390×1040): the central 70 px ROI loses less than 1e-4."""
    camera = CameraConfig()
    v = natural_vignetting(camera)
    roi = Window.centred(camera.width_px, camera.height_px, 70, 70)
    assert v[Window(0, 0, camera.width_px, camera.height_px).inner(roi)].min() > 1 - 1e-4
    assert v.max() <= 1 and v[0, 0] < 0.995                     # but the corners do fall off
    short = natural_vignetting(CameraConfig(focal_length_mm=8, width_px=160, height_px=120))
    r2 = (79.5 ** 2 + 59.5 ** 2) * 0.00645 ** 2
    assert short[0, 0] == pytest.approx((64 / (64 + r2)) ** 2, rel=1e-12)


def test_nonlinearity_is_off_by_default_and_keeps_zero_and_full_well():
    model = SensorModel.from_config(CameraConfig(), SimulationConfig(), np.random.default_rng(0))
    assert model.nonlinearity_rel == 0
    fw = 18000.0
    np.testing.assert_allclose(convert_nonlinear(np.array([0.0, fw]), 0.02, fw), [0.0, fw])
    assert convert_nonlinear(np.array([fw / 2]), 0.02, fw)[0] == pytest.approx(fw / 2 * 0.99)
