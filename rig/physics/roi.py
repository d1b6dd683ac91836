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

On a steep glossy lobe the ROI mean is not the value at the ROI centre: its pixels see the sample from
directions up to the footprint apart (rig.physics.footprint). A quadratic fit of the log block means
estimates that bias; where it is resolved, the mean is corrected to the centre value and the texture is the
spread of the block means about the fitted lobe rather than about their mean (which would count the lobe as
texture). The corrected value weighs the blocks unevenly (rig.physics.footprint.centre_weights: the fitted
surface at the centre): what that adds to the texture's variance of an even mean is its own component
(u_lobe).

Which ROIs are corrected: those whose bias is resolved (RESOLVED_Z), and every ROI on a clear slope (SLOPE_F),
resolved or not. A slope alone makes the ROI mean exceed the centre value (the mean of an exponential), so on a
flank the bias is there whatever the fit makes of it; and the slope's test does not select on the bias estimate's
own noise. Deciding on that estimate alone did: of the views on a lobe whose bias stands 2–3 u(bias) from 0, those
whose texture made it look larger were corrected, slightly over (the issue's glossy lobe 0–1° off the mirror
direction: z +0.4…+0.7), and those whose texture made it look smaller were left with |b̂| as u, which fell short of
the bias they kept (z −1.5…−1.7; a steep RetroPhong's clear flanks: corrected at random, z std 2.5). Where a ROI
is not corrected its u is the spread about the block means' plane (a slope averages out of the mean), and at a
peak whose curvature the fit sees at CURVED_Z, short of RESOLVED_Z, the bias it estimates is left in the mean and
counted as u_lobe (issue 34).

A row does not take u_mean as it is: where the grain is about a block wide, neighbouring blocks correlate
beyond what one ROI's edge covariance shows, so the row's texture is the ROI's independent-block variance
times the neighbours' correlation pooled over the run's views (rig.physics.block_correlation, issue 34). Both
come from the ROI's pattern, its log block means about the lobe fit's quadratic whether or not the lobe is
corrected: about a plane, an unresolved flank's curvature counted as texture, in its own u (beside its bias in
u_lobe) and in the pooled covariances of every view of its footprint class. On the glossy sample's views,
rendered over 100 texture seeds, the error over u of a flat view was 0.78–0.91 and of a corrected one 0.77–0.81
with the patterns about the plane; with the quadratic's, 0.97–1.10 and 0.92–0.94 (docs/uncertainty.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rig.physics.footprint import NO_LOBE, LobeFit, fit_lobe

#: Side (px) of the blocks whose means give the uncertainty of the ROI mean.
BLOCK_PX = 10


@dataclass(frozen=True)
class RoiStats:
    """Summary of one ROI, in the image's unit (e.g. cd/m²)."""

    mean: float            # ROI mean, corrected to the value at the ROI centre where the lobe is corrected
    u_mean: float          # standard uncertainty of the mean from the spread of block means (about the lobe)
    u_mean_noise: float    # from the propagated per-pixel variance alone
    std: float             # pixel standard deviation (texture + noise)
    n: int                 # pixels
    n_blocks: int          # whole blocks used for u_mean
    lobe: LobeFit = NO_LOBE  # the fit of the block means' curvature (rig.physics.footprint)
    #: What correcting the lobe adds to u_mean (the texture through the centre weights, in quadrature), or the
    #: bias left uncorrected on a clear flank (below)
    u_lobe: float = 0.0
    corrected: bool = False  # the mean is corrected to the ROI centre for the lobe (the fit resolves it)
    #: The ROI's texture pattern, (rows, cols): the log block means about the lobe fit's quadratic (`quadratic`),
    #: or where the grid is too small for that fit, the block means about their plane over their mean. What the
    #: texture's covariances are estimated from (rig.physics.block_correlation), kept so that views of the same
    #: sample area can be compared (rig.physics.static_texture). None for a black ROI.
    pattern: np.ndarray | None = None

    @property
    def quadratic(self) -> bool:
        """Whether `pattern` is about the lobe fit's quadratic (else about the block means' plane)."""
        return self.lobe.residual is not None

    @property
    def u_texture(self) -> float:
        """Non-uniformity (texture) part of u_mean: √(u_mean² − u_mean_noise²), 0 if noise explains it all."""
        return float(np.sqrt(max(self.u_mean ** 2 - self.u_mean_noise ** 2, 0.0)))

    def u_luminance(self, calibration_u_rel: float) -> float:
        """Standard uncertainty of `mean` as a luminance: block spread ⊕ lobe correction ⊕ calibration."""
        return float(np.linalg.norm([self.u_mean, self.u_lobe, calibration_u_rel * self.mean]))

    @property
    def lobe_bias_rel(self) -> float:
        """The relative bias `mean` was corrected for (ROI mean / centre value − 1); 0 when not corrected."""
        return self.lobe.bias_rel if self.corrected else 0.0

    @property
    def lobe_slope_rel(self) -> float:
        """The corrected lobe's log-slope at the ROI centre per footprint; 0 when not corrected."""
        return self.lobe.slope_rel if self.corrected else 0.0

    @property
    def centre_weights(self) -> np.ndarray | None:
        """The corrected centre value's weights on the log block means (rig.physics.footprint.centre_weights);
        None when not corrected."""
        return self.lobe.centre_weights if self.corrected else None

    def capture_fields(self) -> dict[str, Any]:
        """The fields of a point's capture record (rig.core.values.PointCapture) that the ROI gives, alike for
        every camera: its value, spread, texture, lobe correction and block pattern."""
        return dict(luminance_cd_m2=self.mean, roi_std_cd_m2=self.std, u_texture_cd_m2=self.u_texture,
                    u_lobe_cd_m2=self.u_lobe, lobe_bias_rel=self.lobe_bias_rel, lobe_width_rel=self.lobe_width_rel,
                    lobe_slope_rel=self.lobe_slope_rel, roi_pattern=self.pattern, roi_pattern_quadratic=self.quadratic,
                    lobe_weights=self.centre_weights)

    @property
    def lobe_width_rel(self) -> float:
        """The corrected lobe's half-width in units of the view footprint; 0 when not corrected (or flat)."""
        return self.lobe.width_rel if self.corrected and np.isfinite(self.lobe.width_rel) else 0.0


def mean_noise(variance: np.ndarray) -> float:
    """Standard uncertainty of the mean of pixels with independent noise of these variances."""
    return float(np.sqrt(np.sum(variance)) / np.size(variance))


def block_means(image: np.ndarray, block_px: int = BLOCK_PX) -> np.ndarray:
    """Means of the whole block_px × block_px blocks tiling `image` from its corner, (rows, cols)."""
    rows, cols = image.shape[0] // block_px, image.shape[1] // block_px
    tiles = image[:rows * block_px, :cols * block_px].reshape(rows, block_px, cols, block_px)
    return tiles.mean(axis=(1, 3))


#: A plane through the block means explains this many times their residual variance (per parameter, an F
#: statistic) when the ROI lies on a lobe's flank: a pure texture gives about 1 (F > 10 by chance: p < 1e-3). On such
#: a clear slope the lobe is corrected whether or not its bias is resolved (module docstring).
SLOPE_F = 10.0


def _about_plane(means: np.ndarray) -> tuple[np.ndarray, int, float]:
    """Block means about their least-squares plane, its degrees of freedom, and the plane's F statistic."""
    rows, cols = means.shape
    n = means.size
    if rows < 2 or cols < 2 or n <= 3:
        return means - means.mean(), n - 1, 0.0
    y, x = np.mgrid[0:rows, 0:cols]
    design = np.stack([np.ones(n), x.ravel() - x.mean(), y.ravel() - y.mean()], axis=1)
    coef = np.linalg.lstsq(design, means.ravel(), rcond=None)[0]
    dev = means - (design @ coef).reshape(rows, cols)
    res = float(np.sum(dev ** 2))
    explained = float(np.sum((means - means.mean()) ** 2)) - res
    return dev, n - 3, explained / 2 / (res / (n - 3)) if res > 0 else (np.inf if explained > 0 else 0.0)


def u_mean_of_blocks(means: np.ndarray, weights: np.ndarray | None = None, fitted: int = 3) -> float:
    """Standard uncertainty of the mean of a grid of block means, neighbours' covariance included; with
    `weights` (rows, cols), of the weighted sum Σ weights·means instead (a corrected lobe's centre value).

    The spread is taken about the least-squares plane through the block means, not about their mean: a
    linear trend across the ROI is the BRDF's slope over the view footprint (a lobe's flank), which the
    ROI mean averages out exactly (the ROI is symmetric about its centre, whose direction the row's angles
    are), so it is no error of the mean; counted as texture it widened u on every sloped point (issue 34).
    The plane's three parameters are taken out of the degrees of freedom; `fitted`: the parameters fitted to
    `means` before (6 for block means flattened by a lobe's quadratic)."""
    dev, dof, _ = _about_plane(means)
    dof -= fitted - 3
    v = np.full(means.shape, 1.0 / means.size) if weights is None else weights
    var = float(np.sum(dev ** 2)) / dof
    products = np.concatenate([(dev[:, :-1] * dev[:, 1:]).ravel(), (dev[:-1, :] * dev[1:, :]).ravel()])
    cov = float(np.clip(products.mean(), 0.0, var)) if products.size else 0.0
    neighbours = float(np.sum(v[:, :-1] * v[:, 1:]) + np.sum(v[:-1, :] * v[1:, :]))
    return float(np.sqrt(max(var * float(np.sum(v ** 2)) + 2 * cov * neighbours, 0.0)))


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
    n, mean = image.size, float(image.mean())
    lobe = fit_lobe(means, block_px, image.shape) if mean > 0 else NO_LOBE
    dev, _, f_plane = _about_plane(means)
    if lobe.trend is None or not (lobe.resolved or f_plane > SLOPE_F):
        # At a peak whose curvature the fit sees short of resolving it (LobeFit.curved), the lobe's curvature
        # biases the mean: the bias it estimates is left in, and counted as its u.
        pattern = lobe.residual if lobe.residual is not None else (dev / mean if mean > 0 else None)
        return RoiStats(mean=mean, u_mean=u_mean_of_blocks(means), u_mean_noise=mean_noise(variance),
                        std=float(image.std(ddof=1)), n=n, n_blocks=int(means.size), lobe=lobe,
                        u_lobe=abs(lobe.bias_rel * mean) if lobe.curved else 0.0, pattern=pattern)
    # The centre value is the ROI mean / (1 + bias); its texture and noise parts scale with it.
    scale = 1.0 / (1.0 + lobe.bias_rel)
    flattened = means / lobe.trend
    u_mean = u_mean_of_blocks(flattened, fitted=6)
    u_centre = u_mean_of_blocks(flattened, lobe.centre_weights, fitted=6)
    return RoiStats(mean=mean * scale, u_mean=u_mean * scale,
                    u_mean_noise=mean_noise(variance) * scale, std=float(image.std(ddof=1)), n=n,
                    n_blocks=int(means.size), lobe=lobe,
                    u_lobe=float(np.sqrt(max(u_centre ** 2 - u_mean ** 2, 0.0))) * scale,
                    corrected=True, pattern=lobe.residual)


def point_flags(stats: RoiStats, min_snr: float, saturated: bool) -> tuple[str, ...]:
    """Flags of a point's ROI luminance: `low_signal` when its mean is within `min_snr` standard
    uncertainties of zero (a value the data barely distinguish from none), `roi_saturated` when ROI pixels
    clipped (the mean is then a lower bound), `narrow_lobe` when the BRDF's lobe is narrower than the ROI's
    angular footprint (the centre value rests on the fitted lobe shape more than on the data near it)."""
    flags = []
    if stats.mean <= min_snr * stats.u_mean:
        flags.append("low_signal")
    if saturated:
        flags.append("roi_saturated")
    if stats.lobe.narrow:
        flags.append("narrow_lobe")
    return tuple(flags)
