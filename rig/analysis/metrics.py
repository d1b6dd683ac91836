"""Goodness of fit exactly as Spieringhs et al. 2023, Eqs. 16, 19, 20 (JOSA A 40(3), 590–601).

`fm` are the measured BRDF values, `fr` the model's, over the same N (incidence, view)
pairs, both unweighted (sr⁻¹): the paper's tables are comparable only so.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike


def _pair(fm: ArrayLike, fr: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    fm, fr = np.asarray(fm, float).ravel(), np.asarray(fr, float).ravel()
    if fm.shape != fr.shape or fm.size == 0:
        raise ValueError(f"need two non-empty arrays of equal length, got {fm.size} and {fr.size}")
    return fm, fr


def rmse(fm: ArrayLike, fr: ArrayLike) -> float:
    """Eq. 16: sqrt(mean((fm − fr)²))."""
    fm, fr = _pair(fm, fr)
    return float(np.sqrt(np.mean((fm - fr) ** 2)))


def nrmse(fm: ArrayLike, fr: ArrayLike) -> float:
    """Eq. 19: Σ|fm − fr| / (max(fm ∪ fr) · N) — a mean absolute error over the largest value."""
    fm, fr = _pair(fm, fr)
    return float(np.sum(np.abs(fm - fr)) / (max(fm.max(), fr.max()) * fm.size))


def ncc(fm: ArrayLike, fr: ArrayLike) -> float:
    """Eq. 20: normalised cross-correlation (Pearson's r); NaN when either side is constant."""
    fm, fr = _pair(fm, fr)
    if np.ptp(fm) == 0 or np.ptp(fr) == 0:
        return float("nan")
    dm, dr = fm - fm.mean(), fr - fr.mean()
    return float(np.sum(dm * dr) / np.sqrt(np.sum(dm ** 2) * np.sum(dr ** 2)))


def goodness_of_fit(fm: ArrayLike, fr: ArrayLike) -> dict[str, float]:
    """The paper's three numbers, keyed as in fit reports."""
    return {"rmse": rmse(fm, fr), "nrmse": nrmse(fm, fr), "ncc": ncc(fm, fr)}
