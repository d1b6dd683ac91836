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
def _moments(rows: int, cols: int) -> tuple[tuple[np.ndarray, ...], np.ndarray, np.ndarray]:
    """The lag matrices K₀, K₁, K₂ of a rows × cols grid (row-major), the moment matrix tr(K_a M K_b M) and
    1ᵀK_b 1 / n² (what each c_b adds to the variance of the mean)."""
    def neighbours(k: int) -> np.ndarray:
        return np.eye(k, k=1) + np.eye(k, k=-1)
    eye_r, eye_c = np.eye(rows), np.eye(cols)
    lags = (np.eye(rows * cols), np.kron(eye_r, neighbours(cols)) + np.kron(neighbours(rows), eye_c),
            np.kron(neighbours(rows), neighbours(cols)))
    y, x = np.mgrid[0:rows, 0:cols]
    design = np.stack([np.ones(rows * cols), x.ravel() - x.mean(), y.ravel() - y.mean()], axis=1)
    residual = np.eye(rows * cols) - design @ np.linalg.pinv(design)
    moment = np.array([[np.trace(ka @ residual @ kb @ residual) for kb in lags] for ka in lags])
    weights = np.array([kb.sum() for kb in lags]) / (rows * cols) ** 2
    for a in (*lags, moment, weights):
        a.flags.writeable = False
    return lags, moment, weights


def mean_variances(pattern: np.ndarray) -> tuple[float, float]:
    """The variance of the mean of the blocks whose pattern (about their plane) this is: with the neighbours'
    covariance from the moments (module docstring; may come out below the next) and with independent blocks."""
    rows, cols = pattern.shape
    lags, moment, weights = _moments(rows, cols)
    p = pattern.ravel()
    q = np.array([p @ k @ p for k in lags])
    independent = float(q[0] / moment[0, 0] * weights[0])
    if min(rows, cols) < MIN_SIDE_BLOCKS:
        return independent, independent
    return float(np.linalg.solve(moment, q) @ weights), independent


def _area_class(area: float) -> int:
    return int(np.searchsorted(AREA_EDGES, area))


class BlockCorrelation:
    """The run's variance inflation of the ROI mean by footprint class, from the views seen so far (`observe`)."""

    def __init__(self) -> None:
        self._sums = np.zeros((len(AREA_EDGES) + 1, 2))        # per class: Σ Var(mean), Σ independent
        self._counts = np.zeros(len(AREA_EDGES) + 1, int)
        self._seen: set[str] = set()

    def observe(self, point_id: str, pattern: np.ndarray, area: float) -> None:
        """Add a view's pattern and its footprint's area (over the normal view's); a view seen before is not
        added again (its row is built again once E⊥ brackets it)."""
        if point_id in self._seen:
            return
        self._seen.add(point_id)
        k = _area_class(area)
        self._sums[k] += mean_variances(pattern)
        self._counts[k] += 1

    def inflation(self, area: float) -> float | None:
        """Var(ROI mean) over the independent-block variance for a footprint of this area (at least 1: the
        neighbours' covariance may only widen u); None while too few views were seen."""
        k = _area_class(area)
        if self._counts[k] >= MIN_VIEWS:
            sums = self._sums[k]
        elif self._counts.sum() >= MIN_VIEWS:
            sums = self._sums.sum(axis=0)
        else:
            return None
        return max(float(sums[0] / sums[1]), 1.0) if sums[1] > 0 else 1.0
