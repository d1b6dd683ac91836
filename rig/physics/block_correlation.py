"""How the ROI's block means correlate, pooled over a run's views: what the texture u of a point needs (issue 34).

A point's texture u (rig.physics.roi) is the uncertainty of the ROI mean from its 7 × 7 block means. Blocks
only a grain or two wide are not independent: neighbours share the grain across their common edge and corner,
and Var(ROI mean) = Σᵢⱼ Cov(bᵢ, bⱼ)/n². `roi.u_mean_of_blocks` adds the edge neighbours' covariance estimated
from the block means about their plane, per ROI. On the simulated sample (docs/uncertainty.md) that falls short
where the grain is coarse against a block, i.e. where the footprint is smallest: a view along the normal, whose
1.9 mm blocks hold two pitches of the 1 mm static grain. Rendered apart over 60 texture seeds, the ROI means'
true error is 1.12 times that u within 20° of the normal, 1.05 at θo 50–70°, 1.02 beyond 70°. Two reasons:
the covariance of residuals about a fitted plane is biased low (their sum over all pairs is 0 by construction:
each estimated covariance lacks about Var(mean)), and the corner neighbours are left out. And per ROI, from 84
products, the covariance is noisy: u itself scatters ±15 % from point to point, which alone costs about 2 %
of k = 2 coverage.

So the correlation is estimated by the method of moments and pooled over the run's views:

- Each view's pattern p (the block means about their plane over their mean: `RoiStats.pattern`) gives the lag
  sums q_a = pᵀ K_a p for a = 0 (each block with itself), 1 (edge neighbours), 2 (corner neighbours). For a
  texture whose covariance is c₀ I + c₁ K₁ + c₂ K₂ (nothing beyond the corner neighbours), with M the plane's
  residual projector, E[q_a] = Σ_b c_b tr(K_a M K_b M): three linear equations give (c₀, c₁, c₂) without the
  plane's bias, and Var(mean) = Σ_b c_b 1ᵀK_b 1 / n².
- Pooled over the views of a footprint class (its area on the sample over the normal view's: AREA_EDGES), the
  ratio of the summed Var(mean) to the summed independent-block variance c₀'/n (c₀' = q₀/(n − 3), what u would
  be with no correlation) is the class's variance inflation; a point's texture u is its own independent-block
  variance times it. The correlation is the sample's and the footprint's, not the point's; pooled, it is
  nearly free of noise, and the point keeps only its own variance (43 degrees of freedom).

On the simulator's views (60 seeds) the ROI means' error over this u is 1.00 ± 0.02 in every θo class, and a
texture-only z covers 94.1 % at k = 2 (std 1.06) where the per-ROI u gave 92.1 % (std 1.13).
"""

from __future__ import annotations

import functools

import numpy as np

#: Footprint classes, by the area of the ROI's footprint on the sample over the normal view's (1/cos θo for a
#: square ROI): θo ≈ 30°, 51°, 70°. A grain's correlation between blocks falls as the blocks stretch.
AREA_EDGES = (1.15, 1.6, 3.0)
#: Views a class needs before its own inflation is used; until then the run's views of every class, and with
#: fewer than that in all, the ROI's own u (`roi.u_mean_of_blocks`). Pooled over 30 views of the simulator's
#: near-normal class the inflation is within 7 % (relative sd) of the whole run's, over 10 within 16 %.
MIN_VIEWS = 30
#: Blocks a pattern needs along each side to tell its neighbours' covariance from its variance: on a 2 × n grid
#: (an ROI of 20–29 px) the plane leaves the three moments dependent (the moment matrix is singular), so such a
#: pattern counts as independent blocks.
MIN_SIDE_BLOCKS = 3


@functools.lru_cache(maxsize=8)
def _moments(rows: int, cols: int, quadratic: bool = False) -> tuple[tuple[np.ndarray, ...], np.ndarray, np.ndarray]:
    """The lag matrices K₀, K₁, K₂ of a rows × cols grid (row-major), the moment matrix tr(K_a M K_b M) and
    1ᵀK_b 1 / n² (what each c_b adds to the variance of the mean). M takes out a plane, or with `quadratic` a
    quadratic surface: what a corrected lobe's pattern is the residual of (rig.physics.roi)."""
    def neighbours(k: int) -> np.ndarray:
        return np.eye(k, k=1) + np.eye(k, k=-1)
    eye_r, eye_c = np.eye(rows), np.eye(cols)
    lags = (np.eye(rows * cols), np.kron(eye_r, neighbours(cols)) + np.kron(neighbours(rows), eye_c),
            np.kron(neighbours(rows), neighbours(cols)))
    y, x = np.mgrid[0:rows, 0:cols]
    xc, yc = x.ravel() - x.mean(), y.ravel() - y.mean()
    design = np.stack([np.ones(rows * cols), xc, yc, *((xc * xc, xc * yc, yc * yc) if quadratic else ())], axis=1)
    residual = np.eye(rows * cols) - design @ np.linalg.pinv(design)
    moment = np.array([[np.trace(ka @ residual @ kb @ residual) for kb in lags] for ka in lags])
    weights = np.array([kb.sum() for kb in lags]) / (rows * cols) ** 2
    for a in (*lags, moment, weights):
        a.flags.writeable = False
    return lags, moment, weights


def _covariances(pattern: np.ndarray, quadratic: bool = False) -> tuple[np.ndarray, float]:
    """The pattern's lag covariances (c₀, c₁, c₂) by the moments (module docstring) and its independent-block
    variance c₀' (what c₀ would be with no correlation); with too few blocks a side, (c₀', 0, 0). `quadratic`:
    the pattern is the residual of a quadratic surface, not of a plane (a corrected lobe's)."""
    rows, cols = pattern.shape
    lags, moment, _ = _moments(rows, cols, quadratic)
    p = pattern.ravel()
    q = np.array([p @ k @ p for k in lags])
    independent = float(q[0] / moment[0, 0])
    if min(rows, cols) < MIN_SIDE_BLOCKS:
        return np.array([independent, 0.0, 0.0]), independent
    return np.linalg.solve(moment, q), independent


def mean_variances(pattern: np.ndarray, quadratic: bool = False) -> tuple[float, float]:
    """The variance of the mean of the blocks whose pattern (about their plane, or their quadratic) this is: with
    the neighbours' covariance from the moments (module docstring; may come out below the next) and with
    independent blocks."""
    covariances, independent = _covariances(pattern, quadratic)
    weights = _moments(*pattern.shape)[2]
    return float(covariances @ weights), independent * float(weights[0])


def _weighted_variance(covariances: np.ndarray, weights: np.ndarray) -> float:
    """Var(Σ weights·blocks) for blocks whose lag covariances are `covariances` (c₀, c₁, c₂)."""
    lags = _moments(*weights.shape)[0]
    v = weights.ravel()
    return float(sum(c * (v @ k @ v) for c, k in zip(covariances, lags)))


def _area_class(area: float) -> int:
    return int(np.searchsorted(AREA_EDGES, area))


class BlockCorrelation:
    """The run's block covariances by footprint class, from the views seen so far (`observe`): the variance
    inflation of the ROI mean (`inflation`) and of any weighted sum of its blocks (`weighted_variance`)."""

    def __init__(self) -> None:
        self._sums = np.zeros((len(AREA_EDGES) + 1, 4))        # per class: Σ c₀, Σ c₁, Σ c₂, Σ c₀'
        self._counts = np.zeros(len(AREA_EDGES) + 1, int)
        self._seen: set[str] = set()

    def observe(self, point_id: str, pattern: np.ndarray, area: float, quadratic: bool = False) -> None:
        """Add a view's pattern (`quadratic`: about a corrected lobe's quadratic) and its footprint's area (over
        the normal view's); a view seen before is not added again (its row is built again once E⊥ brackets it)."""
        if point_id in self._seen:
            return
        self._seen.add(point_id)
        k = _area_class(area)
        covariances, independent = _covariances(pattern, quadratic)
        self._sums[k] += (*covariances, independent)
        self._counts[k] += 1

    def _pooled(self, area: float) -> np.ndarray | None:
        """Σ (c₀, c₁, c₂, c₀') of the footprint's class, of the run's views while it has too few, or None."""
        k = _area_class(area)
        if self._counts[k] >= MIN_VIEWS:
            return self._sums[k]
        if self._counts.sum() >= MIN_VIEWS:
            return self._sums.sum(axis=0)
        return None

    def weighted_variance(self, area: float, weights: np.ndarray) -> float | None:
        """Var(Σ weights·blocks) for a footprint of this area, in units of a block's independent variance c₀'
        (the pooled covariances over the pooled c₀'); None while too few views were seen."""
        sums = self._pooled(area)
        if sums is None:
            return None
        return _weighted_variance(sums[:3], weights) / sums[3] if sums[3] > 0 else float(np.sum(weights ** 2))

    def inflation(self, area: float, shape: tuple[int, int]) -> float | None:
        """Var(ROI mean) over the independent-block variance for a footprint of this area and ROI of `shape`
        blocks (at least 1: the neighbours' covariance may only widen u); None while too few views were seen."""
        n = shape[0] * shape[1]
        ratio = self.weighted_variance(area, np.full(shape, 1.0 / n))
        return None if ratio is None else max(ratio * n, 1.0)
