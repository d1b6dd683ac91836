import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rig.core.values import SensorInfo
from rig.physics.hdr import QUANTISATION_VAR_DN2, merge_exposures, saturation_threshold_dn

SENSOR = SensorInfo(width_px=200, height_px=200, bit_depth=12, gain_dn_per_e=0.25, read_noise_e=8.0,
                    black_level_dn=64.0, calibration_cd_m2_per_dn_s=1.0)
DARK_E_S = 200.0
#: The merge works and returns float32: closed forms hold to its rounding (2⁻²³ ≈ 1.2e-7 per operation).
F32_RTOL = 1e-6


def expose(rng, rate_e_s, exposure_s, n_frames=1, shape=(200, 200), dark=False):
    """Raw frames (n, H, W) of a flat field under the EMVA 1288 model."""
    electrons = rng.poisson((0.0 if dark else rate_e_s) * exposure_s + DARK_E_S * exposure_s,
                            (n_frames,) + shape)
    dn = np.round(SENSOR.gain_dn_per_e * (electrons + rng.normal(0, SENSOR.read_noise_e, electrons.shape))
                  + SENSOR.black_level_dn)
    return np.clip(dn, 0, SENSOR.saturation_dn).astype(np.uint16)


def bracket(rng, rate_e_s, exposures_s, n_frames=1, shape=(200, 200)):
    raw = [expose(rng, rate_e_s, t, n_frames, shape) for t in exposures_s]
    darks = [expose(rng, rate_e_s, t, 1, shape, dark=True)[0] for t in exposures_s]
    return raw, darks


def test_noise_free_samples_give_the_rate_and_the_closed_form_variance():
    rate_dn_s, times = 1.0e4, [0.01, 0.1]
    raw = [np.full((2, 3), 64 + rate_dn_s * t, np.uint16) for t in times]
    darks = [np.full((2, 3), 64, np.uint16)] * 2
    merged = merge_exposures(raw, darks, times, SENSOR)
    np.testing.assert_allclose(merged.rate_dn_s, rate_dn_s, rtol=F32_RTOL)
    read_var = 2 * ((0.25 * 8.0) ** 2 + QUANTISATION_VAR_DN2)
    weights = [t ** 2 / (0.25 * rate_dn_s * t + read_var) for t in times]
    np.testing.assert_allclose(merged.var_rate, 1 / sum(weights), rtol=F32_RTOL)
    assert np.all(merged.n_used == 2) and not merged.saturated.any() and not merged.clipped.any()


def test_dark_frame_variance_is_split_out_in_closed_form():
    """Frames' own noise + the subtracted darks' noise = the merge variance; 2 frames, 3 darks."""
    rate_dn_s, times = 1.0e4, np.array([0.01, 0.1])
    raw = [np.full((2, 2, 3), 64 + rate_dn_s * t, np.uint16) for t in times]
    darks = [np.full((3, 2, 3), 64, np.uint16)] * 2
    merged = merge_exposures(raw, darks, times, SENSOR)
    rho2 = (0.25 * 8.0) ** 2 + QUANTISATION_VAR_DN2
    frame_var, dark_var = (0.25 * rate_dn_s * times + rho2) / 2, rho2 / 3 * np.ones(2)
    weights = times ** 2 / (frame_var + dark_var)
    share = weights / weights.sum()
    np.testing.assert_allclose(merged.var_dark, np.sum(share ** 2 * dark_var / times ** 2), rtol=F32_RTOL)
    np.testing.assert_allclose(merged.var_rate - merged.var_dark, np.sum(share ** 2 * frame_var / times ** 2),
                               rtol=F32_RTOL)
    np.testing.assert_allclose(merged.var_rate, 1 / weights.sum(), rtol=F32_RTOL)


def test_a_shared_dark_correlates_two_merges_by_var_dark():
    """Two captures that reuse one dark share its noise: their covariance is var_dark, not 0."""
    rng = np.random.default_rng(6)
    times = [0.004, 0.016]
    darks = [expose(rng, 0.0, t, 1, dark=True)[0] for t in times]
    merges = [merge_exposures([expose(rng, 2.0e4, t, 4) for t in times], darks, times, SENSOR) for _ in range(2)]
    first, second = (m.rate_dn_s.ravel() for m in merges)
    covariance = np.cov(first, second)[0, 1]
    assert merges[0].var_dark.mean() > 0.3 * merges[0].var_rate.mean()        # dark-dominated on purpose
    assert covariance / merges[0].var_dark.mean() == pytest.approx(1.0, abs=0.06)


def test_merge_of_poisson_frames_is_unbiased_and_its_variance_is_right():
    rng = np.random.default_rng(1)
    rate_e_s, times = 2.0e5, [0.001, 0.004, 0.016]
    raw, darks = bracket(rng, rate_e_s, times)
    merged = merge_exposures(raw, darks, times, SENSOR)
    truth = rate_e_s * SENSOR.gain_dn_per_e
    n = merged.rate_dn_s.size
    assert abs(merged.rate_dn_s.mean() - truth) < 4 * np.sqrt(merged.var_rate.mean() / n)
    assert merged.rate_dn_s.var(ddof=1) / merged.var_rate.mean() == pytest.approx(1.0, abs=0.04)


def test_maximum_likelihood_weights_beat_equal_weights():
    rng = np.random.default_rng(2)
    times = [0.0005, 0.016]
    raw, darks = bracket(rng, 1.0e5, times)
    merged = merge_exposures(raw, darks, times, SENSOR)
    equal = np.mean([(r[0] - d.astype(float)) / t for r, d, t in zip(raw, darks, times)], axis=0)
    assert merged.rate_dn_s.var() < 0.5 * equal.var()


def test_saturated_samples_are_excluded():
    rng = np.random.default_rng(3)
    rate_e_s, times = 1.0e6, [0.001, 0.004, 0.064]       # the longest collects 4× the full scale
    raw, darks = bracket(rng, rate_e_s, times)
    merged = merge_exposures(raw, darks, times, SENSOR)
    assert merged.saturated.all() and np.all(merged.n_used == 2) and not merged.clipped.any()
    truth = rate_e_s * SENSOR.gain_dn_per_e
    assert (abs(merged.rate_dn_s.mean() / truth - 1)
            < 4 * np.sqrt(merged.var_rate.mean() / merged.rate_dn_s.size) / truth)
    assert merged.rate_dn_s.var(ddof=1) / merged.var_rate.mean() == pytest.approx(1.0, abs=0.04)


def test_pixels_saturated_in_every_exposure_are_lower_bounds():
    rng = np.random.default_rng(4)
    times = [0.01, 0.02]
    raw, darks = bracket(rng, 1.0e7, times, shape=(5, 5))
    merged = merge_exposures(raw, darks, times, SENSOR)
    assert merged.clipped.all() and np.all(merged.n_used == 0)
    assert np.all(merged.rate_dn_s <= 1.0e7 * SENSOR.gain_dn_per_e)
    np.testing.assert_allclose(merged.rate_dn_s, (raw[0][0] - darks[0].astype(float)) / 0.01, rtol=F32_RTOL)
    assert np.all(np.isfinite(merged.var_rate)) and np.all(merged.var_rate > 0)
    assert np.all(merged.var_dark > 0) and np.all(merged.var_dark < merged.var_rate)


def test_a_saturated_frame_drops_its_whole_exposure_at_that_pixel():
    times = [0.01, 0.1]
    high = np.full((2, 1, 1), 100, np.uint16)
    high[1] = SENSOR.saturation_dn                     # one of two averaged frames clips
    raw = [np.full((1, 1), 74, np.uint16), high]
    darks = [np.full((1, 1), 64, np.uint16)] * 2
    merged = merge_exposures(raw, darks, times, SENSOR)
    assert merged.n_used[0, 0] == 1 and merged.saturated[0, 0]
    assert merged.rate_dn_s[0, 0] == pytest.approx(1000.0)


def test_frame_averaging_divides_the_frame_noise():
    rng = np.random.default_rng(5)
    times = [0.004]
    single = merge_exposures(*bracket(rng, 2.0e5, times), times, SENSOR)
    raw, darks = bracket(rng, 2.0e5, times, n_frames=4)
    averaged = merge_exposures(raw, darks, times, SENSOR)
    assert averaged.var_rate.mean() < 0.5 * single.var_rate.mean()
    assert averaged.rate_dn_s.var(ddof=1) / averaged.var_rate.mean() == pytest.approx(1.0, abs=0.04)


def test_saturation_threshold_is_just_below_full_scale():
    assert SENSOR.black_level_dn < saturation_threshold_dn(SENSOR) < SENSOR.saturation_dn
    assert saturation_threshold_dn(SENSOR, 0.0) == pytest.approx(SENSOR.saturation_dn, abs=1e-9)


def test_mismatched_inputs_are_refused():
    frame = np.zeros((2, 2), np.uint16)
    with pytest.raises(ValueError):
        merge_exposures([frame, frame], [frame], [0.1, 0.2], SENSOR)
    with pytest.raises(ValueError):
        merge_exposures([frame], [frame], [0.0], SENSOR)


@settings(max_examples=50, deadline=None)
@given(rate_dn_ms=st.integers(0, 60), times_ms=st.lists(st.integers(1, 400), min_size=1, max_size=5),
       seed=st.integers(0, 2 ** 16))
def test_consistent_samples_merge_to_their_rate_in_any_order(rate_dn_ms, times_ms, seed):
    """Every unsaturated sample says X: any weighting returns X, whatever the order."""
    times = np.array(times_ms) / 1000.0
    raw = [np.full((1, 2), min(64 + rate_dn_ms * t_ms, SENSOR.saturation_dn), np.uint16) for t_ms in times_ms]
    darks = [np.full((1, 2), 64, np.uint16)] * len(times)
    order = np.random.default_rng(seed).permutation(len(times))
    merged = merge_exposures([raw[i] for i in order], darks, times[order], SENSOR)
    if not merged.clipped.any():
        np.testing.assert_allclose(merged.rate_dn_s, 1000.0 * rate_dn_ms, rtol=F32_RTOL)
    assert np.all(np.isfinite(merged.rate_dn_s)) and np.all(merged.var_rate > 0)
