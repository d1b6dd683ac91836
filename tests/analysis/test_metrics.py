"""Goodness-of-fit metrics against closed forms (Spieringhs et al. 2023 Eqs. 16, 19, 20)."""

import math

import numpy as np
import pytest

from rig.analysis.metrics import goodness_of_fit, ncc, nrmse, rmse

FM = [1.0, 2.0, 3.0]
FR = [1.0, 2.0, 5.0]


def test_rmse_closed_form():
    assert rmse(FM, FR) == pytest.approx(math.sqrt(4 / 3))
    assert rmse(FM, FM) == pytest.approx(0.0, abs=1e-15)


def test_nrmse_divides_by_the_largest_of_both_sets_and_n():
    # Σ|fm − fr| = 2, max(fm ∪ fr) = 5 (a model value), N = 3
    assert nrmse(FM, FR) == pytest.approx(2 / 15)
    # the maximum may come from the measurement as well
    assert nrmse([1.0, 8.0], [2.0, 8.0]) == pytest.approx(1 / 16)


def test_ncc_closed_forms():
    assert ncc([1, 2, 3], [1, 3, 2]) == pytest.approx(0.5)
    assert ncc(FM, [10, 20, 30]) == pytest.approx(1.0)
    assert ncc(FM, [3, 2, 1]) == pytest.approx(-1.0)
    rng = np.random.default_rng(0)
    a, b = rng.normal(size=50), rng.normal(size=50)
    assert ncc(a, b) == pytest.approx(np.corrcoef(a, b)[0, 1])
    assert ncc(a, 3 * b + 7) == pytest.approx(ncc(a, b))        # invariant to gain and offset


def test_ncc_of_a_constant_model_is_undefined_not_a_number():
    assert math.isnan(ncc(FM, [0.2, 0.2, 0.2]))


def test_goodness_of_fit_keys_and_errors():
    assert goodness_of_fit(FM, FR) == pytest.approx({"rmse": rmse(FM, FR), "nrmse": nrmse(FM, FR),
                                                     "ncc": ncc(FM, FR)}, rel=1e-12)
    with pytest.raises(ValueError, match="equal length"):
        rmse([1.0, 2.0], [1.0])
    with pytest.raises(ValueError):
        nrmse([], [])
