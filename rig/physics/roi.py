"""Statistics of the region of interest (ROI) of a merged luminance image.

Pure numpy. The measurand is the mean luminance over the ROI. Its pixels are
not independent: a road marking's glass beads and grains span several pixels,
and the merged image's pixel noise sits on top of that texture. The standard
uncertainty of the mean is therefore taken from the spread of means of blocks
larger than a grain (10 × 10 px by default): block means are nearly
independent, and their spread contains both the pixel noise and the texture,
whereas std/√n would assume independent pixels and understate it by roughly
the square root of the number of pixels per grain. Blocks only a couple of
grains wide are still correlated with their neighbours, so the covariance of
edge-sharing blocks, estimated from the same blocks, is added to the variance
of their mean (clipped at zero: it may only widen the uncertainty). The propagated per-pixel
variance alone is reported next to it to show how much of the total is noise,
and the difference of the two squares is the texture's share.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Side (px) of the blocks whose means give the uncertainty of the ROI mean.
BLOCK_PX = 10


@dataclass(frozen=True)
class RoiStats:
    """Summary of one ROI, in the image's unit (e.g. cd/m²)."""

    mean: float
    u_mean: float          # standard uncertainty of the mean from the spread of block means
    u_mean_noise: float    # from the propagated per-pixel variance alone
    std: float             # pixel standard deviation (texture + noise)
    n: int                 # pixels
    n_blocks: int          # whole blocks used for u_mean

    @property
    def u_texture(self) -> float:
        """Non-uniformity (texture) part of u_mean: √(u_mean² − u_mean_noise²), 0 if noise explains it all."""
        return float(np.sqrt(max(self.u_mean ** 2 - self.u_mean_noise ** 2, 0.0)))


def mean_noise(variance: np.ndarray) -> float:
    """Standard uncertainty of the mean of pixels with independent noise of these variances."""
    return float(np.sqrt(np.sum(variance)) / np.size(variance))


def block_means(image: np.ndarray, block_px: int = BLOCK_PX) -> np.ndarray:
    """Means of the whole block_px × block_px blocks tiling `image` from its corner, (rows, cols)."""
    rows, cols = image.shape[0] // block_px, image.shape[1] // block_px
    tiles = image[:rows * block_px, :cols * block_px].reshape(rows, block_px, cols, block_px)
    return tiles.mean(axis=(1, 3))


def u_mean_of_blocks(means: np.ndarray) -> float:
    """Standard uncertainty of the mean of a grid of block means, neighbours' covariance included."""
    dev = means - means.mean()
    n = means.size
    var = float(np.sum(dev ** 2)) / (n - 1)
    products = np.concatenate([(dev[:, :-1] * dev[:, 1:]).ravel(), (dev[:-1, :] * dev[1:, :]).ravel()])
    cov = float(np.clip(products.mean(), 0.0, var)) if products.size else 0.0
    return float(np.sqrt((n * var + 2 * products.size * cov) / n ** 2))


def roi_statistics(image: np.ndarray, variance: np.ndarray, block_px: int = BLOCK_PX) -> RoiStats:
    """Mean of an ROI image and its uncertainties.

    Parameters
    ----------
    image : (H, W) array
        ROI of the merged image.
    variance : (H, W) array
        Per-pixel variance of `image` (unit²), e.g. from the HDR merge.
    block_px : int
        Block side (px); it should exceed the texture's grain so that block
        means are nearly independent. Pixels beyond the last whole block count
        for the mean but not for u_mean.
    """
    image = np.asarray(image, dtype=float)
    variance = np.asarray(variance, dtype=float)
    if image.shape != variance.shape or image.ndim != 2:
        raise ValueError(f"image {image.shape} and variance {variance.shape} must be the same 2-D shape")
    means = block_means(image, block_px)
    if means.size < 2:
        raise ValueError(f"ROI {image.shape} holds fewer than two {block_px}×{block_px} px blocks")
    n = image.size
    return RoiStats(mean=float(image.mean()),
                    u_mean=u_mean_of_blocks(means),
                    u_mean_noise=mean_noise(variance),
                    std=float(image.std(ddof=1)),
                    n=n, n_blocks=int(means.size))


def point_flags(stats: RoiStats, min_snr: float, saturated: bool) -> tuple[str, ...]:
    """Flags of a point's ROI luminance: `low_signal` when its mean is within `min_snr` standard
    uncertainties of zero (a value the data barely distinguish from none), `roi_saturated` when ROI pixels
    clipped (the mean is then a lower bound)."""
    flags = []
    if stats.mean <= min_snr * stats.u_mean:
        flags.append("low_signal")
    if saturated:
        flags.append("roi_saturated")
    return tuple(flags)
