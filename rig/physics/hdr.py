"""Noise-optimal HDR merge of raw exposures of a linear camera (Granados et al. 2010).

Pure numpy, no I/O. A calibrated luminance camera is linear, so every
unsaturated, dark-subtracted sample yₖ − darkₖ divided by its exposure time tₖ
is an unbiased estimate of the same signal rate X (DN/s). The maximum-likelihood
combination weights each by the inverse of its variance (EMVA 1288 noise model),
which is why this merge, unlike OpenCV's Debevec/Robertson merges, has a known
variance per pixel that the uncertainty budget can use.

`merge_exposures` is the one the rig uses: it merges in float32, one pass over
the frames by the compiled kernel `_merge_kernel.c` (one band of rows per CPU on a
full frame), or, where the package was installed without a C compiler, block by
block of rows in numpy (see its Notes). `merge_exposures_reference` states the same
merge in whole-array numpy, in float64; the tests and benchmarks/merge_speed.py hold
both fast ones to it.
"""

from __future__ import annotations

import functools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rig.core.bands import run_in_bands
from rig.core.values import SensorInfo

try:
    from rig.physics import _merge_kernel
except ImportError:            # installed without a C compiler: the numpy block merge below does it all
    _merge_kernel = None  # type: ignore[assignment]

#: Fraction of the range above black level given up below full scale: sensors bend
#: before they clip, so samples this close to full scale are not trusted.
SATURATION_MARGIN_REL = 0.01
#: Variance of uniform quantisation by 1 DN (DN²).
QUANTISATION_VAR_DN2 = 1.0 / 12.0
#: Re-weighting passes after the signal-independent first pass; the estimate
#: converges in one or two because the weights depend on it only weakly.
REWEIGHT_PASSES = 2
#: Pixels merged at a time: a block's dozen float32 working arrays (~3 MB) stay in
#: the CPU's cache, so the frames are read from memory once, whatever the passes.
BLOCK_PX = 1 << 16
#: What the compiled kernel reads (the buffer formats 'H', 'f', 'd').
_KERNEL_DTYPES = (np.dtype(np.uint16), np.dtype(np.float32), np.dtype(np.float64))
#: Dark frames of at least this many pixels get their median from a histogram (OpenCV),
#: 20× faster than numpy's partition on a full frame; smaller ones use np.median.
HISTOGRAM_MEDIAN_MIN_PX = 1 << 16
#: OpenCV counts in float32, exact up to 2²⁴ per bin: larger darks use np.median.
HISTOGRAM_MEDIAN_MAX_PX = 1 << 24


@dataclass(frozen=True)
class HdrMerge:
    """Per-pixel result of a merge; all arrays have the window's (height, width)."""

    rate_dn_s: np.ndarray      # signal rate above dark, DN/s (float32; float64 from the reference)
    var_rate: np.ndarray       # its variance, (DN/s)²
    var_dark: np.ndarray       # the part of var_rate due to the subtracted dark frames, (DN/s)²
    n_used: np.ndarray         # number of exposures merged into each pixel (int)
    saturated: np.ndarray      # saturated in the longest exposure (bool)
    clipped: np.ndarray        # saturated in every exposure: rate is a lower bound (bool)


def saturation_threshold_dn(sensor: SensorInfo, margin_rel: float = SATURATION_MARGIN_REL) -> float:
    """Raw level (DN) at and above which a sample counts as saturated."""
    return sensor.saturation_dn - margin_rel * (sensor.saturation_dn - sensor.black_level_dn)


def _stack(frames: np.ndarray) -> np.ndarray:
    """(n, H, W) view of one frame (H, W) or of a stack of frames."""
    frames = np.asarray(frames)
    return frames.reshape((-1,) + frames.shape[-2:])


def _checked(raw_dn: Sequence[np.ndarray], dark_dn: Sequence[np.ndarray],
             exposures_s: Sequence[float]) -> tuple[np.ndarray, list[np.ndarray], list[np.ndarray]]:
    """Exposure times (s) and the (n, H, W) frame and dark stacks, or ValueError."""
    t = np.asarray(exposures_s, dtype=float)
    if not (len(raw_dn) == len(dark_dn) == t.size) or t.size == 0:
        raise ValueError("need one frame stack, one dark and one exposure time per exposure")
    if np.any(t <= 0):
        raise ValueError(f"exposure times must be positive, got {t.tolist()}")
    return t, [_stack(f) for f in raw_dn], [_stack(d) for d in dark_dn]


def _read_var_dn2(sensor: SensorInfo) -> float:
    """ρ² = (K σ_read)² + 1/12: the variance of a frame without signal or dark current (DN²)."""
    return (sensor.gain_dn_per_e * sensor.read_noise_e) ** 2 + QUANTISATION_VAR_DN2


def _median_dn(dark_mean_dn: np.ndarray) -> float:
    """np.median of a mean dark frame (H, W); of a large uint16 one from its histogram.

    Exactly np.median (the mean of the two middle values for an even count): a
    uint16 frame's values are integers, so their histogram with one bin per value
    holds every order statistic.
    """
    if not (dark_mean_dn.dtype == np.uint16 and HISTOGRAM_MEDIAN_MIN_PX <= dark_mean_dn.size
            <= HISTOGRAM_MEDIAN_MAX_PX):
        return float(np.median(dark_mean_dn))
    import cv2  # here: 0.2 s to import, paid only by runs that merge full frames

    bins = int(dark_mean_dn.max()) + 1
    counts = cv2.calcHist([np.ascontiguousarray(dark_mean_dn)], [0], None, [bins], [0, bins]).ravel()
    below = np.cumsum(counts, dtype=np.float64)
    middle = np.searchsorted(below, [(dark_mean_dn.size - 1) // 2 + 1, dark_mean_dn.size // 2 + 1])
    return float(middle.mean())


def merge_exposures(raw_dn: Sequence[np.ndarray], dark_dn: Sequence[np.ndarray],
                    exposures_s: Sequence[float], sensor: SensorInfo,
                    margin_rel: float = SATURATION_MARGIN_REL) -> HdrMerge:
    """Maximum-likelihood signal rate from exposures of one window.

    Parameters
    ----------
    raw_dn : sequence of arrays
        Per exposure k, one raw frame (H, W) or a stack (nₖ, H, W) of frames of
        that exposure, which are averaged first (frame averaging).
    dark_dn : sequence of arrays
        Per exposure k, the dark frame (H, W) or a stack (mₖ, H, W) of dark
        frames with the same exposure time and window, shutter closed. The same
        dark is subtracted from all nₖ frames, so its noise does not average down
        with nₖ.
    exposures_s : sequence of float
        Realised exposure time tₖ (s) of each exposure.
    sensor : SensorInfo
        Gain K (DN/e⁻, positive), read noise (e⁻), black level and bit depth.
    margin_rel : float
        Saturation margin, see `saturation_threshold_dn`.

    Notes
    -----
    X̂ = Σ wₖ rₖ / Σ wₖ with rₖ = (ȳₖ − d̄ₖ)/tₖ, wₖ = tₖ²/σₖ² and var X̂ = 1/Σ wₖ, where
    σₖ² = (K(S + D) + ρ²)/nₖ + δₖ, δₖ = (K D + ρ²)/mₖ, ρ² = (K σ_read)² + 1/12,
    S = X tₖ the signal and D the dark-current signal (DN). S comes from the previous pass's
    X̂, not from the sample itself, so weights do not correlate with the sample's
    noise (a sample that came out high would otherwise get a lower weight); D is
    the median of the dark frame for the same reason. The first pass uses S = 0.
    Samples at or above the saturation threshold get no weight; an exposure with
    a saturated frame at a pixel is dropped for that pixel altogether, since its
    unsaturated frames are a biased selection. A pixel saturated in every
    exposure gets the shortest exposure's clipped rate and variance as a lower
    bound and `clipped` set.

    δₖ is the variance of the subtracted dark d̄ₖ. It is shared by all nₖ frames and
    by every other merge that reuses the dark, so it neither averages down with
    frames nor over points; `var_dark` = Σ wₖ² δₖ/tₖ² / (Σ wₖ)² is its share of var X̂
    (the rest, var X̂ − var_dark, is the frames' own noise).

    Speed: the weight is rewritten wₖ = aₖ/(max(X̂, 0) + bₖ), aₖ = nₖtₖ/K and
    bₖ = (K D + ρ² + nₖδₖ)/(K tₖ), two operations per pixel. The compiled kernel
    runs every pass on a pixel in registers, a row at a time, with the GIL released
    (`_merge_compiled`); the numpy fallback merges BLOCK_PX pixels at a time, every
    pass on a block while it is in the cache. With a single exposure (a metered ROI's
    usual point) the weight cancels and X̂ = r at every pass: the kernel writes r and
    var = (max(r, 0) + b)/a without passes. Both work in float32: frame sums of
    integer DN are exact in float32, and the rounding of a mean (2⁻²⁴ relative,
    < 3·10⁻⁴ DN) is a thousandth of the quantisation noise (0.29 DN). The outputs
    are float32 too.
    """
    plan = _plan(raw_dn, dark_dn, exposures_s, sensor, margin_rel)
    height, width = plan.frames[0].shape[1:]
    out = HdrMerge(rate_dn_s=np.empty((height, width), np.float32), var_rate=np.empty((height, width), np.float32),
                   var_dark=np.empty((height, width), np.float32), n_used=np.empty((height, width), np.uint8),
                   saturated=np.empty((height, width), bool), clipped=np.empty((height, width), bool))
    if _merge_kernel is not None:
        _merge_compiled(plan, [out.rate_dn_s, out.var_rate, out.var_dark, out.n_used, out.saturated, out.clipped])
        return out
    rows = max(1, BLOCK_PX // max(width, 1))
    for y0 in range(0, height, rows):
        block = slice(y0, y0 + rows)
        _merge_block([f[:, block] for f in plan.frames], [d[:, block] for d in plan.darks], plan, out, block)
    return out


def merged_rate(raw_dn: Sequence[np.ndarray], dark_dn: Sequence[np.ndarray], exposures_s: Sequence[float],
                sensor: SensorInfo, margin_rel: float = SATURATION_MARGIN_REL) -> np.ndarray:
    """`merge_exposures`' rate alone, (H, W) float32: what a saved image needs. The compiled kernel then
    writes nothing else (the variances and flags would double its memory traffic); the numpy fallback
    merges in full."""
    if _merge_kernel is None:
        return merge_exposures(raw_dn, dark_dn, exposures_s, sensor, margin_rel).rate_dn_s
    plan = _plan(raw_dn, dark_dn, exposures_s, sensor, margin_rel)
    rate = np.empty(plan.frames[0].shape[1:], np.float32)
    _merge_compiled(plan, [rate, None, None, None, None, None])
    return rate


@dataclass(frozen=True)
class _Plan:
    """A merge's checked inputs and per-exposure constants (merge_exposures' Notes)."""

    frames: list[np.ndarray]            # (nₖ, H, W) per exposure
    darks: list[np.ndarray]             # (mₖ, H, W) per exposure
    consts: list[dict[str, float]]      # 1/tₖ ("inv_t"), aₖ, bₖ, cₖ
    threshold_dn: float                 # saturation threshold
    thresholds: list[float]             # the same, to compare each exposure's frames with (_threshold_for)
    shortest: int
    longest: int


def _plan(raw_dn: Sequence[np.ndarray], dark_dn: Sequence[np.ndarray], exposures_s: Sequence[float],
          sensor: SensorInfo, margin_rel: float) -> _Plan:
    """A merge's inputs checked, and its per-exposure constants (merge_exposures' Notes)."""
    t, frames, darks = _checked(raw_dn, dark_dn, exposures_s)
    if not sensor.gain_dn_per_e > 0:
        raise ValueError(f"the sensor's gain must be positive, got {sensor.gain_dn_per_e} DN/e⁻")
    k_gain = sensor.gain_dn_per_e
    n = np.array([f.shape[0] for f in frames], float)
    m = np.array([d.shape[0] for d in darks], float)
    dark_signal_dn = np.array([max(_median_dn(d[0] if len(d) == 1 else d.mean(axis=0)) - sensor.black_level_dn,
                                   0.0) for d in darks])
    floor_var = k_gain * dark_signal_dn + _read_var_dn2(sensor)       # per frame, without signal
    delta = floor_var / m                                               # δₖ
    per_exposure = {
        "inv_t": 1.0 / t, "a": n * t / k_gain, "b": (floor_var + n * delta) / (k_gain * t), "c": delta / t ** 2}
    threshold_dn = saturation_threshold_dn(sensor, margin_rel)
    return _Plan(frames, darks, [{key: float(v[k]) for key, v in per_exposure.items()} for k in range(t.size)],
                 threshold_dn, [_threshold_for(f.dtype, threshold_dn) for f in frames], int(np.argmin(t)),
                 int(np.argmax(t)))


def _merge_compiled(plan: _Plan, outputs: list[np.ndarray | None]) -> None:
    """merge_exposures' pass over the pixels by the compiled kernel (_merge_kernel.c) into `outputs` (HdrMerge's
    arrays in its order; None: not wanted, all but the rate): one band of rows per CPU for a full frame
    (rig.core.bands). The kernel reads uint16, float32 and float64 frames; others are converted to float32 first."""
    def readable(frame: np.ndarray) -> np.ndarray:
        return frame if frame.dtype.isnative and frame.dtype in _KERNEL_DTYPES else frame.astype(np.float32)
    peaks = [readable(f[0] if len(f) == 1 else f.max(axis=0)) for f in plan.frames]
    def column(key: str) -> list[float]:
        return [c[key] for c in plan.consts]
    merge_rows = functools.partial(
        _merge_kernel.merge_rows, [readable(_mean_dn(f)) for f in plan.frames], peaks,
        [readable(_mean_dn(d)) for d in plan.darks], [_threshold_for(p.dtype, plan.threshold_dn) for p in peaks],
        column("inv_t"), column("a"), column("b"), column("c"), plan.shortest, plan.longest, REWEIGHT_PASSES, outputs)
    rate = outputs[0]
    assert rate is not None, "the rate is always merged"
    run_in_bands(merge_rows, *rate.shape)


def _threshold_for(dtype: np.dtype, threshold_dn: float) -> float:
    """The saturation threshold to compare frames of `dtype` with: for integer frames the next
    integer (the same samples count), so that numpy compares them as integers, not as float64 copies."""
    return float(threshold_dn) if not np.issubdtype(dtype, np.integer) else int(np.ceil(threshold_dn))


def _mean_dn(stack: np.ndarray) -> np.ndarray:
    """Mean (H, W) of a stack of frames (n, H, W): the frame itself when n = 1, else float32."""
    if len(stack) == 1:
        return stack[0]
    mean = stack.sum(axis=0, dtype=np.float32)
    mean *= 1.0 / len(stack)
    return mean


def _merge_block(frames: list[np.ndarray], darks: list[np.ndarray], plan: _Plan, out: HdrMerge,
                 block: slice) -> None:
    """merge_exposures on a block of rows, written into out[block] (see merge_exposures' Notes).

    Fewest passes over the block: an exposure without saturated pixels in the block keeps its
    scalar aₖ, the first exposure of a sum writes the sum, and max(X̂, 0) compares with an array
    (numpy's maximum with a scalar is 5× slower)."""
    saturated = [(f[0] if len(f) == 1 else f.max(axis=0)) >= thr for f, thr in zip(frames, plan.thresholds)]
    clipped = functools.reduce(np.logical_and, saturated)
    rates: list[np.ndarray] = []
    scales: list[float | np.ndarray] = []                   # aₖ where usable, else 0
    for k, (f, d, c) in enumerate(zip(frames, darks, plan.consts)):
        rate = np.subtract(_mean_dn(f), _mean_dn(d), dtype=np.float32)
        rate *= c["inv_t"]
        rates.append(rate)
        unusable = saturated[k] & ~clipped if k == plan.shortest else saturated[k]   # clipped: the shortest's rate
        scales.append(np.multiply(~unusable, c["a"], dtype=np.float32) if unusable.any() else c["a"])
    zero = np.zeros_like(rates[0])
    weight, weight_sum, weighted, dark_part = (np.empty_like(zero) for _ in range(4))
    merged = out.rate_dn_s[block]
    for p in range(1 + REWEIGHT_PASSES):
        signal = np.maximum(merged, zero, out=weighted) if p else None      # max(X̂, 0) of the previous pass
        for k, (rate, a, c) in enumerate(zip(rates, scales, plan.consts)):
            w = weight_sum if k == 0 else weight
            if signal is None:
                np.multiply(a, 1.0 / c["b"], out=w)
            else:
                np.add(signal, c["b"], out=w)
                np.divide(a, w, out=w)                      # wₖ
            if p == REWEIGHT_PASSES:                        # Σ wₖ² δₖ/tₖ²
                np.square(w, out=zero if k else dark_part)
                np.multiply(zero if k else dark_part, c["c"], out=zero if k else dark_part)
                if k:
                    dark_part += zero
            if k == 0:
                np.multiply(w, rate, out=merged)
                continue
            weight_sum += w
            w *= rate
            merged += w
        merged /= weight_sum
    var_rate = np.divide(1.0, weight_sum, out=out.var_rate[block])
    dark_part *= var_rate
    np.multiply(dark_part, var_rate, out=out.var_dark[block])
    np.subtract(len(saturated), functools.reduce(np.add, (s.view(np.uint8) for s in saturated)), out=out.n_used[block])
    out.saturated[block] = saturated[plan.longest]
    out.clipped[block] = clipped


def merge_exposures_reference(raw_dn: Sequence[np.ndarray], dark_dn: Sequence[np.ndarray],
                              exposures_s: Sequence[float], sensor: SensorInfo,
                              margin_rel: float = SATURATION_MARGIN_REL) -> HdrMerge:
    """`merge_exposures` (same arguments, same Notes) in whole-array float64 numpy, as it reads.

    Not used by the rig: it is the definition the tests and benchmarks/merge_speed.py hold the
    fast merge to. It keeps (E, H, W) stacks of every intermediate: ~0.3 s on a full frame.
    """
    t, frames, darks = _checked(raw_dn, dark_dn, exposures_s)
    threshold = saturation_threshold_dn(sensor, margin_rel)
    k_gain = sensor.gain_dn_per_e
    read_var = _read_var_dn2(sensor)
    t3 = t[:, None, None]

    saturated = np.stack([np.any(f >= threshold, axis=0) for f in frames])          # (E, H, W)
    dark_mean = np.stack([d.mean(axis=0, dtype=float) for d in darks])
    rates = (np.stack([f.mean(axis=0, dtype=float) for f in frames]) - dark_mean) / t3
    n_frames = np.array([f.shape[0] for f in frames], float)[:, None, None]
    n_darks = np.array([d.shape[0] for d in darks], float)[:, None, None]
    dark_signal_dn = np.maximum(np.median(dark_mean, axis=(1, 2)) - sensor.black_level_dn, 0.0)
    floor_var = k_gain * dark_signal_dn[:, None, None] + read_var      # per frame, without signal
    dark_frame_var = floor_var / n_darks                                # δₖ

    def inverse_variance(rate_dn_s: np.ndarray) -> np.ndarray:
        """wₖ = 1/var(rₖ) for a signal rate estimate (DN/s), (E, H, W)."""
        frame_var = (k_gain * np.maximum(rate_dn_s, 0.0) * t3 + floor_var) / n_frames
        return t3 ** 2 / (frame_var + dark_frame_var)

    clipped = np.asarray(saturated.all(axis=0))
    shortest = np.arange(t.size)[:, None, None] == np.argmin(t)
    usable = ~saturated | (clipped & shortest)       # clipped pixels fall back on the shortest exposure
    rate = np.zeros(rates.shape[1:])
    for _ in range(1 + REWEIGHT_PASSES):
        weights = np.where(usable, inverse_variance(rate[None]), 0.0)
        weight_sum = weights.sum(axis=0)
        rate = np.sum(weights * rates, axis=0) / weight_sum

    var_dark = np.sum(weights ** 2 * dark_frame_var / t3 ** 2, axis=0) / weight_sum ** 2
    return HdrMerge(rate_dn_s=rate, var_rate=1.0 / weight_sum, var_dark=var_dark,
                    n_used=(~saturated).sum(axis=0), saturated=saturated[int(np.argmax(t))], clipped=clipped)
