"""Angular footprint of a measurement and the error of averaging a curved lobe over it (pure numpy).

A point's value is the mean luminance over its ROI, but every ROI pixel sees its patch of sample
from a slightly different direction: the view direction from a sample point to the camera is the
pixel's ray reversed, so the ROI's view directions spread over the angle its pixels subtend at the
lens (≈ 0.5° half-angle for 100 px of 6.45 µm at f = 50 mm), whatever the pose. On a diffuse sample
that does not matter; on a steep glossy lobe (modified Phong n ≳ 1000) the BRDF changes by tens of
percent across that spread and the ROI mean is not the value at the ROI centre, which the row's
nominal angles stand for. Near the peak the mean is low (the lobe is concave there), on the flanks
it is high (the lobe is convex in log and the mean of an exponential exceeds the exponential of the
mean). The lamp beam is collimated (rig.physics.optics): one incident direction lights the whole
spot, so the illumination footprint is 0 and only the view directions are averaged.

The bias is estimated from the data: log(block means) of the ROI, a smooth surface in the block position, is
fitted by a quadratic; a Gaussian-like lobe is exactly quadratic in log, and the view direction is (to first
order) linear in the pixel position. The ROI mean of the fitted surface over its value at the ROI centre
gives the relative bias (its fit covariance says whether it is resolved), the fit's residual spread is the
texture (which reaches the corrected value through `centre_weights`), and the curvature gives the lobe's
width in pixels, hence in units of the footprint (`narrow_lobe` when the lobe is narrower than the
footprint). The fitted slope at the centre says how fast the value changes with the view direction: on a
lobe's flank an axis error of 0.01° moves a modified-Phong n = 10000 value by ~5 %, which rig.physics.budget
turns into a component.

Texture (3 % grains, 10 % direction-dependent glints on the simulated sample) makes a fit on a flat
ROI show spurious gradient and curvature. Correcting by such a noise-driven bias would only add
noise (about 0.2 block spreads, i.e. more than the ROI mean's own uncertainty), so the bias counts
only when it is resolved, |bias| ≥ RESOLVED_Z · u(bias), or where the ROI lies on a clear slope (rig.physics.roi
decides, SLOPE_F). Elsewhere the ROI mean is left alone and the component is 0.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from rig.core.values import Window
from rig.physics.optics import CameraOptics, ray_directions

#: A lobe bias counts (is corrected, with its uncertainty in the budget) from this many of its standard
#: uncertainties: the benchmark (benchmarks/footprint_study.py) shows that spurious curvature from texture
#: stays below it on flat samples while real lobes of the issue's glossy sample pass it by far.
RESOLVED_Z = 3.0
#: An unresolved concave bias (the mean below the centre value: a peak) this many of its standard uncertainties
#: from 0 is counted as u where the mean is left uncorrected, slope or no slope: at the peak of the issue's glossy
#: lobe (modified Phong n = 3000) the ROI mean is 1.6–1.8 % below the centre value with u(bias) 0.6 %, short of
#: RESOLVED_Z in about half the views, and with no slope it went uncounted (those views' z averaged −2.9). A flat
#: texture passes it in 0.6 % of views (Z ≤ −2.5 of a normal law).
CURVED_Z = 2.5


def view_footprint_deg(optics: CameraOptics, roi: Window) -> float:
    """Half-angle (degrees) of the cone of viewing directions the ROI averages over.

    The largest angle between the view direction of the ROI centre and those of its corners. The view
    direction from a sample point to the camera is the reversed ray of the pixel that sees it, and the
    angle between two rays is the same in every frame, so the footprint does not depend on the motor
    angles (as long as the ROI lies on the sample, which the planner ensures). The illumination's
    footprint is 0: the lamp beam is collimated.
    """
    u = np.array([roi.x0, roi.x0 + roi.width, roi.x0, roi.x0 + roi.width, roi.x0 + roi.width / 2], float)
    v = np.array([roi.y0, roi.y0, roi.y0 + roi.height, roi.y0 + roi.height, roi.y0 + roi.height / 2], float)
    rays = ray_directions(optics, np.eye(3), u, v)
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    cos = np.clip(rays[:4] @ rays[4], -1.0, 1.0)
    return float(np.degrees(np.arccos(cos.min())))


@dataclass(frozen=True)
class LobeFit:
    """What the quadratic fit of log(block means) says about the ROI (see the module docstring)."""

    bias_rel: float         # ROI mean / value at the ROI centre − 1, from the fitted surface
    u_bias_rel: float       # standard uncertainty of bias_rel (fit covariance, residual spread)
    resolved: bool          # |bias_rel| ≥ RESOLVED_Z · u_bias_rel: the bias counts (so does a clear slope's)
    width_rel: float        # lobe's half-width (e^-½ of its peak, narrowest direction) / ROI half-diagonal
    residual_rel: float     # standard deviation of the log block means about the fit (texture), relative
    slope_rel: float = 0.0  # |∇ log f| at the ROI centre, per ROI half-diagonal (i.e. per footprint)
    #: The fitted lobe at the block centres relative to the ROI mean (rows, cols): dividing the block means
    #: by it flattens the lobe and leaves the texture. None without a fit.
    trend: np.ndarray | None = None
    #: The corrected centre value's linear weights on the log block means (rows, cols; `centre_weights`): what
    #: the texture moves it by. None without a fit.
    centre_weights: np.ndarray | None = None
    #: The log block means about the fitted surface (rows, cols): the texture, with the lobe's curvature out (a
    #: flank's pattern about a plane keeps it, and the curvature is no texture). None without a fit.
    residual: np.ndarray | None = None

    @property
    def curved(self) -> bool:
        """Not resolved, but −bias ≥ CURVED_Z · u(bias): a peak's curvature the fit sees (no slope shows it) but does
        not correct; its bias is left in the mean and counted as u (rig.physics.roi)."""
        return not self.resolved and -self.bias_rel >= CURVED_Z * self.u_bias_rel > 0

    @property
    def narrow(self) -> bool:
        """The lobe is resolved and narrower than the footprint: the ROI sees more than the lobe's core."""
        return self.resolved and self.width_rel < 1.0


#: No lobe: a flat ROI, or one the fit cannot take (too few blocks, non-positive block means).
NO_LOBE = LobeFit(bias_rel=0.0, u_bias_rel=0.0, resolved=False, width_rel=math.inf, residual_rel=0.0)


def _design(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Quadratic surface basis, constant term first: 1, x, y, x², xy, y²."""
    return np.stack([np.ones_like(x), x, y, x * x, x * y, y * y], axis=-1)


@dataclass(frozen=True)
class _Lattice:
    """What fit_lobe needs of an ROI's block and pixel positions; the same for every point of a run."""

    scale: float                # ROI half-diagonal, px: keeps the design well scaled
    design: np.ndarray          # quadratic basis at the block centres (rows, cols, 6)
    solve: np.ndarray           # least-squares solution operator (XᵀX)⁻¹Xᵀ (6, rows·cols)
    inv_normal: np.ndarray      # (XᵀX)⁻¹ (6, 6)
    pixel_basis: np.ndarray     # q − q(centre) basis at the pixel centres, no constant (height·width, 5)


@functools.lru_cache(maxsize=16)
def _lattice(rows: int, cols: int, block_px: int, height: int, width: int) -> _Lattice:
    scale = math.hypot(height, width) / 2
    yb = ((np.arange(rows) + 0.5) * block_px - height / 2) / scale
    xb = ((np.arange(cols) + 0.5) * block_px - width / 2) / scale
    design = _design(*np.meshgrid(xb, yb))
    flat = design.reshape(-1, 6)
    inv_normal = np.linalg.inv(flat.T @ flat)
    yp = (np.arange(height) + 0.5 - height / 2) / scale
    xp = (np.arange(width) + 0.5 - width / 2) / scale
    arrays = (design, inv_normal @ flat.T, inv_normal, _design(*np.meshgrid(xp, yp)).reshape(-1, 6)[:, 1:])
    for a in arrays:
        a.flags.writeable = False           # shared by every call
    return _Lattice(scale, *arrays)


def _neighbour_correlation(res: np.ndarray) -> float:
    """Mean correlation of edge-sharing residuals (clipped at 0): blocks only a few grains wide share texture."""
    products = np.concatenate([(res[:, :-1] * res[:, 1:]).ravel(), (res[:-1, :] * res[1:, :]).ravel()])
    var = float(np.mean(res ** 2))
    return float(np.clip(products.mean() / var, 0.0, 1.0)) if products.size and var > 0 else 0.0


def fit_lobe(means: np.ndarray, block_px: int, roi_shape: tuple[int, int]) -> LobeFit:
    """Fit log(block means) (rows, cols) of an ROI of `roi_shape` pixels by a quadratic in position.

    The bias is the pixel mean of exp(q − q(centre)) over the whole ROI minus 1, q the fitted surface, so
    that it matches the ROI mean (which counts every pixel) and does not depend on the fit's constant.
    Its uncertainty propagates the fit's covariance (residual variance × (XᵀX)⁻¹, widened by the
    residuals' neighbour correlation as for the ROI mean) through the bias's gradient.
    """
    rows, cols = means.shape
    if rows * cols < 12 or rows < 3 or cols < 3 or not np.all(means > 0):
        return NO_LOBE
    height, width = roi_shape
    lattice = _lattice(rows, cols, block_px, height, width)
    design_flat, scale = lattice.design.reshape(-1, 6), lattice.scale
    log_means = np.log(means).ravel()
    coef = lattice.solve @ log_means
    # A block's mean exceeds the lobe at its centre by ≈ side²/24 · (|∇q|² + ∇²q) (the mean of an
    # exponential over the block): refit once without it, or a steep lobe's curvature comes out too flat.
    side2 = (block_px / scale) ** 2
    grad_x = coef[1] + 2 * coef[3] * design_flat[:, 1] + coef[4] * design_flat[:, 2]
    grad_y = coef[2] + coef[4] * design_flat[:, 1] + 2 * coef[5] * design_flat[:, 2]
    within = side2 / 24 * (grad_x ** 2 + grad_y ** 2 + 2 * (coef[3] + coef[5]))
    coef = lattice.solve @ (log_means - within)
    res = log_means - within - design_flat @ coef
    dof = res.size - 6
    s2 = float(res @ res) / dof * (1.0 + 4.0 * _neighbour_correlation(res.reshape(rows, cols)))
    cov = s2 * lattice.inv_normal
    basis = lattice.pixel_basis
    ratio = np.exp(basis @ coef[1:])
    bias = float(ratio.mean() - 1.0)
    grad = np.concatenate([[0.0], (ratio[:, None] * basis).mean(axis=0)])
    u_bias = float(math.sqrt(max(grad @ cov @ grad, 0.0)))

    hessian = np.array([[2 * coef[3], coef[4]], [coef[4], 2 * coef[5]]])
    steepest = -float(np.linalg.eigvalsh(hessian)[0])            # most negative curvature of log f
    width_rel = 1.0 / math.sqrt(steepest) if steepest > 0 else math.inf
    # The block means' model, the within-block excess included: on a lobe a few blocks wide the excess is
    # several per cent, and block means flattened without it kept it as texture.
    trend = np.exp(lattice.design[..., 1:] @ coef[1:] + within.reshape(rows, cols)) / (1.0 + bias)
    return LobeFit(bias_rel=bias, u_bias_rel=u_bias, resolved=abs(bias) >= RESOLVED_Z * u_bias,
                   width_rel=width_rel, residual_rel=float(np.sqrt(float(res @ res) / dof)),
                   slope_rel=float(math.hypot(coef[1], coef[2])), trend=trend,
                   centre_weights=centre_weights(lattice, trend), residual=res.reshape(rows, cols))


def centre_weights(lattice: _Lattice, trend: np.ndarray) -> np.ndarray:
    """The weights L of the corrected centre value's relative error on the log block means p: δ = L·p.

    The centre value is the ROI mean over (1 + bias). A texture p (small, in log) moves the ROI mean by w·p, w the
    blocks' shares of it (the lobe's trend), and the fit by S p (S the least-squares operator): the bias by the
    trend-weighted mean of the fitted surface's change less its change at the centre, which is w·P p − (S p)₀ with
    P = X S the fit's projector. So δ = (S p)₀ + w·(I − P) p: the fitted surface's value at the ROI centre plus
    the texture's share the quadratic cannot take. The ROI mean's own texture error and the bias's move together
    and mostly cancel; counted apart (the mean's u ⊕ the bias's u) they overstate a narrow lobe's u about twice.
    For a flat ROI w is uniform, (I − P) w = 0 and L is the intercept's row: on a 7 × 7 grid its ‖L‖² is 3.7/n,
    what predicting the centre from a quadratic costs against the plain mean (1/n)."""
    w = (trend / trend.sum()).ravel()
    design = lattice.design.reshape(-1, 6)
    weights = lattice.solve[0] + w - (w @ design) @ lattice.solve
    return weights.reshape(trend.shape)
