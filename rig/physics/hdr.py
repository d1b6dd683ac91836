"""Noise-optimal HDR merge of raw exposures of a linear camera (Granados et al. 2010).

Pure numpy, no I/O. A calibrated luminance camera is linear, so every
unsaturated, dark-subtracted sample yₖ − darkₖ divided by its exposure time tₖ
is an unbiased estimate of the same signal rate X (DN/s). The maximum-likelihood
combination weights each by the inverse of its variance (EMVA 1288 noise model),
which is why this merge, unlike OpenCV's Debevec/Robertson merges, has a known
variance per pixel that the uncertainty budget can use.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rig.core.values import SensorInfo

#: Fraction of the range above black level given up below full scale: sensors bend
#: before they clip, so samples this close to full scale are not trusted.
SATURATION_MARGIN_REL = 0.01
#: Variance of uniform quantisation by 1 DN (DN²).
QUANTISATION_VAR_DN2 = 1.0 / 12.0
#: Re-weighting passes after the signal-independent first pass; the estimate
#: converges in one or two because the weights depend on it only weakly.
REWEIGHT_PASSES = 2


@dataclass(frozen=True)
class HdrMerge:
    """Per-pixel result of a merge; all arrays have the window's (height, width)."""

    rate_dn_s: np.ndarray      # signal rate above dark, DN/s (float64)
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
        Gain K (DN/e⁻), read noise (e⁻), black level and bit depth.
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
    """
    t = np.asarray(exposures_s, dtype=float)
    if not (len(raw_dn) == len(dark_dn) == t.size) or t.size == 0:
        raise ValueError("need one frame stack, one dark and one exposure time per exposure")
    if np.any(t <= 0):
        raise ValueError(f"exposure times must be positive, got {t.tolist()}")
    frames = [_stack(f) for f in raw_dn]
    darks = [_stack(d) for d in dark_dn]
    threshold = saturation_threshold_dn(sensor, margin_rel)
    k_gain = sensor.gain_dn_per_e
    read_var = (k_gain * sensor.read_noise_e) ** 2 + QUANTISATION_VAR_DN2
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
