"""The block-wise float32 merge (merge_exposures) against its float64 definition (merge_exposures_reference).

Tolerances, from float32 rounding: each mean and rate carries a relative rounding of
~2⁻²⁴ ≈ 6e-8 per operation, a few dozen operations deep, so variances agree to rtol
1e-5. A rate is a difference ȳ − d̄ that can be near 0, where a relative tolerance means
nothing: its rounding is at most ~1e-7 of the samples (≤ 4095 DN, i.e. < 1e-3 DN), far
below its own noise, so rates are compared within 1e-4 of their standard deviation.
Masks and counts are integers: identical.
"""

import numpy as np
import pytest

from rig.core.bands import PARALLEL_MIN_PX
from rig.core.values import SensorInfo
from rig.physics import hdr
from rig.physics.hdr import merge_exposures, merge_exposures_reference, merged_rate, saturation_threshold_dn

SENSOR = SensorInfo(width_px=300, height_px=200, bit_depth=12, gain_dn_per_e=0.25, read_noise_e=8.0,
                    black_level_dn=64.0, calibration_cd_m2_per_dn_s=1.0)


@pytest.fixture(autouse=True, params=["compiled", "numpy"])
def implementation(request, monkeypatch):
    """Every test runs on the compiled kernel and on the numpy fallback of an install without a C compiler."""
    if request.param == "numpy":
        monkeypatch.setattr(hdr, "_merge_kernel", None)
    elif hdr._merge_kernel is None:
        pytest.skip("rig.physics._merge_kernel was not built (see tests/physics/test_hdr.py)")
    return request.param


def raw_stack(rng, rate_e_s, exposure_s, n_frames, shape):
    """(n, H, W) uint16 frames of a scene of per-pixel rate (e⁻/s) plus 200 e⁻/s dark current."""
    electrons = rng.poisson((rate_e_s + 200.0) * exposure_s, (n_frames,) + shape)
    dn = np.rint(0.25 * (electrons + rng.normal(0, 8.0, electrons.shape)) + 64.0)
    return np.clip(dn, 0, SENSOR.saturation_dn).astype(np.uint16)


def scene(rng, shape, times, n_frames=1, n_darks=1, spread=2.0):
    """Frames and darks per exposure of a log-normal scene spanning from unlit to clipped in every exposure."""
    rate = rng.lognormal(np.log(3e5), spread, shape)
    raw = [raw_stack(rng, rate, t, n_frames, shape) for t in times]
    darks = [raw_stack(rng, 0.0, t, n_darks, shape) for t in times]
    return raw, darks


def assert_same_merge(raw, darks, times):
    fast, ref = (merge(raw, darks, times, SENSOR) for merge in (merge_exposures, merge_exposures_reference))
    sd = np.sqrt(ref.var_rate)
    np.testing.assert_array_less(np.abs(fast.rate_dn_s - ref.rate_dn_s), 1e-4 * sd)
    np.testing.assert_allclose(fast.var_rate, ref.var_rate, rtol=1e-5)
    np.testing.assert_allclose(fast.var_dark, ref.var_dark, rtol=1e-5)
    for mask in ("n_used", "saturated", "clipped"):
        np.testing.assert_array_equal(getattr(fast, mask), getattr(ref, mask))
    return ref


@pytest.mark.parametrize("shape", [(70, 70), (200, 300)], ids=["roi", "frame-like"])
@pytest.mark.parametrize("times, n_frames, n_darks", [
    ([0.011], 1, 1),                              # the usual point: one exposure
    ([0.02], 3, 2),                               # one exposure, frames and darks averaged
    ([0.001, 0.004, 0.016], 1, 1),                # a bracket, some pixels saturated in the longest
    ([0.002, 0.02, 0.2], 3, 2),                   # frame averaging, darks averaged too
    ([0.05, 0.01, 0.2], 2, 4),                    # shortest exposure not first
], ids=["single", "single-averaged", "bracket", "averaged", "unordered"])
def test_fast_merge_equals_the_reference(shape, times, n_frames, n_darks):
    rng = np.random.default_rng(sum(shape) + len(times) + n_frames)
    raw, darks = scene(rng, shape, times, n_frames, n_darks)
    ref = assert_same_merge(raw, darks, times)
    if len(times) > 1:                         # the case covers saturated and clipped pixels and some unlit
        assert ref.saturated.any() and ref.clipped.any() and (ref.n_used == len(times)).any()


def test_fast_merge_equals_the_reference_across_blocks_and_with_a_large_dark():
    """A frame larger than a merge block and than the histogram median's threshold (its own code path)."""
    rng = np.random.default_rng(11)
    times = [0.002, 0.016]
    raw, darks = scene(rng, (260, 300), times)
    darks = [d + rng.integers(0, 3, d.shape, dtype=np.uint16) for d in darks]    # an even count, ties
    assert_same_merge(raw, darks, times)


def test_fast_merge_equals_the_reference_on_float_frames_and_single_frames():
    rng = np.random.default_rng(12)
    times = [0.004, 0.032]
    raw, darks = scene(rng, (30, 40), times)
    assert_same_merge([r[0].astype(float) for r in raw], [d[0].astype(float) for d in darks], times)


def test_fast_merge_equals_the_reference_on_views_cut_from_a_larger_window():
    """The capture merges its ROI as strided views of the window's frame stacks, not as copies."""
    rng = np.random.default_rng(13)
    times = [0.002, 0.016]
    raw, darks = scene(rng, (90, 120), times, n_frames=2)
    roi = (slice(None), slice(10, 80), slice(25, 95))
    ref = assert_same_merge([r[roi] for r in raw], [d[roi] for d in darks], times)
    assert ref.rate_dn_s.shape == (70, 70)


def test_fast_merge_equals_the_reference_with_frame_and_dark_counts_that_differ_between_exposures():
    rng = np.random.default_rng(14)
    times, n_frames, n_darks = [0.001, 0.008, 0.064], [1, 3, 2], [2, 1, 4]
    rate = rng.lognormal(np.log(3e5), 2.0, (40, 50))
    raw = [raw_stack(rng, rate, t, n, rate.shape) for t, n in zip(times, n_frames)]
    darks = [raw_stack(rng, 0.0, t, m, rate.shape) for t, m in zip(times, n_darks)]
    ref = assert_same_merge(raw, darks, times)
    assert ref.saturated.any() and ref.clipped.any()


def test_fast_merge_equals_the_reference_on_averaged_float32_stacks():
    """Float frames (e.g. a driver that returns float32) take the float threshold and the float mean."""
    rng = np.random.default_rng(15)
    times = [0.004, 0.032]
    raw, darks = scene(rng, (30, 40), times, n_frames=3, n_darks=2)
    assert_same_merge([r.astype(np.float32) for r in raw], [d.astype(np.float32) for d in darks], times)


def test_fast_merge_equals_the_reference_where_every_pixel_is_clipped():
    """A block without a usable sample: every pixel falls back on the shortest exposure."""
    rng = np.random.default_rng(16)
    times = [0.02, 0.01, 0.04]
    raw = [raw_stack(rng, 1.0e8, t, 2, (20, 30)) for t in times]
    darks = [raw_stack(rng, 0.0, t, 1, (20, 30)) for t in times]
    ref = assert_same_merge(raw, darks, times)
    assert ref.clipped.all() and ref.saturated.all() and not ref.n_used.any()


def test_samples_just_below_the_threshold_count_as_unsaturated_in_both():
    threshold = saturation_threshold_dn(SENSOR)
    raw = [np.array([[int(np.floor(threshold)), int(np.ceil(threshold))]], np.uint16)]
    darks = [np.full((1, 2), 64, np.uint16)]
    ref = assert_same_merge(raw, darks, [0.01])
    np.testing.assert_array_equal(ref.saturated, [[False, True]])


def test_a_sensor_without_gain_is_refused():
    frame = np.zeros((2, 2), np.uint16)
    no_gain = SensorInfo(width_px=2, height_px=2, bit_depth=12, gain_dn_per_e=0.0, read_noise_e=8.0,
                         black_level_dn=64.0, calibration_cd_m2_per_dn_s=1.0)
    with pytest.raises(ValueError, match="gain"):
        merge_exposures([frame], [frame], [0.1], no_gain)


def test_frames_of_other_types_and_byte_orders_merge_like_the_reference():
    """int32 and big-endian uint16 frames: the compiled kernel reads them as float32 copies."""
    rng = np.random.default_rng(17)
    times = [0.004, 0.032]
    raw, darks = scene(rng, (30, 40), times)
    assert_same_merge([r.astype(np.int32) for r in raw], [d.astype(">u2") for d in darks], times)


def test_a_full_frame_merges_in_bands_like_the_reference():
    """More rows than workers, an odd count, and above PARALLEL_MIN_PX: the bands cover every row once."""
    rng = np.random.default_rng(18)
    times = [0.001, 0.008]
    shape = (PARALLEL_MIN_PX // 200 + 7, 201)
    raw, darks = scene(rng, shape, times)
    assert_same_merge(raw, darks, times)


def test_more_exposures_than_the_kernel_specialises_for_merge_like_the_reference():
    """Five exposures: the compiled kernel's general loop (it unrolls only up to four)."""
    rng = np.random.default_rng(19)
    times = [0.0005, 0.001, 0.004, 0.016, 0.064]
    raw, darks = scene(rng, (40, 50), times)
    ref = assert_same_merge(raw, darks, times)
    assert ref.saturated.any() and (ref.n_used == len(times)).any()


@pytest.mark.parametrize("shape", [(40, 50), (PARALLEL_MIN_PX // 200 + 7, 201)], ids=["small", "in-bands"])
def test_the_rate_alone_is_the_full_merges_rate(shape):
    """merged_rate (a saved image's merge: the kernel writes no variances or flags) gives merge_exposures' rate,
    bit for bit, with saturated and clipped pixels in the frame."""
    rng = np.random.default_rng(20)
    times = [0.001, 0.004, 0.016]
    raw, darks = scene(rng, shape, times, n_frames=2)
    full = merge_exposures(raw, darks, times, SENSOR)
    assert full.clipped.any() and full.saturated.any()
    rate = merged_rate(raw, darks, times, SENSOR)
    assert rate.dtype == np.float32
    np.testing.assert_array_equal(rate, full.rate_dn_s)
