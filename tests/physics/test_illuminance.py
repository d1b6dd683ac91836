"""E⊥ from meter readings: the statistical part pools scatter with the spec and adds the ranges' uncertainty."""

import math

import numpy as np
import pytest

from rig.physics.illuminance import PRIOR_DOF, estimate


def pooled_u(values, repeatability_rel):
    """The statistical part without range uncertainty, written out."""
    n, mean = len(values), float(np.mean(values))
    observed = float(np.var(values, ddof=1)) if n > 1 else 0.0
    return math.sqrt(((n - 1) * observed + PRIOR_DOF * (repeatability_rel * mean) ** 2) / (n - 1 + PRIOR_DOF) / n)


@pytest.mark.parametrize("values", [[500.0], [498.0, 500.0, 502.0, 500.0]])
def test_without_range_uncertainty_the_statistical_part_is_the_pooled_spread(values):
    est = estimate(np.array(values), 12.0, 0.002, 0.01)
    assert est.value_lx == pytest.approx(np.mean(values))
    assert est.u_stat_lx == pytest.approx(pooled_u(values, 0.002), rel=1e-12)
    assert est.u_cal_lx == pytest.approx(0.01 * np.mean(values))
    assert (est.n, est.rig_time_s) == (len(values), 12.0)


def test_a_single_reading_on_one_range():
    """n = 1: u_stat² = (repeatability·E)² + (u_range·E)²."""
    est = estimate(np.array([400.0]), 0.0, 0.003, 0.0, np.array([0.004]))
    assert est.u_stat_lx == pytest.approx(400.0 * math.hypot(0.003, 0.004), rel=1e-12)


def test_the_range_part_does_not_average_down():
    """Readings on one range share its gain error: u_range = u·mean however many readings there are."""
    values = np.array([498.0, 500.0, 502.0, 500.0])
    est = estimate(values, 0.0, 0.002, 0.0, np.full(4, 0.005))
    assert est.u_stat_lx == pytest.approx(math.hypot(pooled_u(values, 0.002), 0.005 * 500.0), rel=1e-12)


def test_readings_on_different_ranges_add_their_parts_linearly():
    """Fully correlated (conservative): |Σ uᵢ·Eᵢ| / n = (0.01·100 + 0.02·200) / 2 = 2.5 lx."""
    values = np.array([100.0, 200.0])
    est = estimate(values, 0.0, 0.0, 0.0, np.array([0.01, 0.02]))
    assert est.u_stat_lx == pytest.approx(math.hypot(pooled_u(values, 0.0), 2.5), rel=1e-12)


def test_a_scalar_range_uncertainty_applies_to_every_reading():
    values = np.array([300.0, 310.0, 290.0])
    assert estimate(values, 0.0, 0.002, 0.0, 0.01) == estimate(values, 0.0, 0.002, 0.0, np.full(3, 0.01))
