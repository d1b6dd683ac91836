"""brdf_from_luminance (rig.physics.illuminance): the measurement equation f_r = L / (E⊥ cos θi) and its GUM
uncertainty, vectorised, finite and flagged towards grazing incidence."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rig.physics.illuminance import GRAZING_LIMIT_DEG, brdf_from_luminance


def test_closed_form_at_60_degrees():
    result = brdf_from_luminance(100.0, 1.0, 1000.0, 10.0, 60.0, 0.1)
    assert result.illuminance_lx == pytest.approx(500.0)
    assert result.brdf_per_sr == pytest.approx(0.2)
    u_rel = np.sqrt(0.01 ** 2 + 0.01 ** 2 + (np.tan(np.pi / 3) * np.deg2rad(0.1)) ** 2)
    assert result.u_brdf_per_sr == pytest.approx(0.2 * u_rel)
    assert not result.grazing_incidence


@pytest.mark.parametrize("theta_deg, u_rel", [(30, 0.001), (60, 0.003), (80, 0.010), (85, 0.020), (88, 0.050)])
def test_angle_sensitivity_table(theta_deg, u_rel):
    """GUM sensitivity of f = L / (E⊥ cos θi) to θi: u_θ = 0.1° alone gives u_rel = tan θi · u_θ, these values."""
    result = brdf_from_luminance(50.0, 0.0, 2000.0, 0.0, theta_deg, 0.1)
    assert result.u_brdf_per_sr / result.brdf_per_sr == pytest.approx(u_rel, rel=0.02)


def test_vectorised_over_broadcast_inputs():
    theta = np.array([[0.0, 30.0, 60.0]])
    lum = np.array([[10.0], [20.0]])
    result = brdf_from_luminance(lum, 0.0, 100.0, 0.0, theta, 0.0)
    assert result.brdf_per_sr.shape == (2, 3)
    np.testing.assert_allclose(result.brdf_per_sr, lum / (100.0 * np.cos(np.deg2rad(theta))))
    np.testing.assert_allclose(result.u_brdf_per_sr, 0.0)


def test_grazing_incidence_is_flagged_and_finite():
    theta = np.array([87.9, 88.0, 89.99999999, 90.0, 95.0, 180.0])
    result = brdf_from_luminance(10.0, 0.1, 1000.0, 5.0, theta, 0.05)
    np.testing.assert_array_equal(result.grazing_incidence, [False, True, True, True, True, True])
    for values in (result.brdf_per_sr, result.u_brdf_per_sr, result.illuminance_lx):
        assert np.all(np.isfinite(values)) and np.all(values > 0)


def test_unlit_roi_has_a_finite_uncertainty():
    result = brdf_from_luminance(0.0, 0.01, 1000.0, 5.0, 45.0, 0.05)
    assert result.brdf_per_sr == 0.0
    assert result.u_brdf_per_sr == pytest.approx(0.01 / (1000.0 * np.cos(np.pi / 4)))


def test_non_positive_illuminance_is_refused():
    with pytest.raises(ValueError):
        brdf_from_luminance(1.0, 0.0, [1000.0, 0.0], 0.0, 0.0, 0.0)


@settings(max_examples=200, deadline=None)
@given(lum=st.floats(0, 1e6), u_lum=st.floats(0, 1e4), e_normal=st.floats(1e-3, 1e6),
       u_e=st.floats(0, 1e3), theta=st.floats(0, 180), u_theta=st.floats(0, 5))
def test_always_finite_and_consistent(lum, u_lum, e_normal, u_e, theta, u_theta):
    result = brdf_from_luminance(lum, u_lum, e_normal, u_e, theta, u_theta)
    assert np.isfinite(result.brdf_per_sr) and np.isfinite(result.u_brdf_per_sr)
    assert result.u_brdf_per_sr >= 0
    assert result.brdf_per_sr * result.illuminance_lx == pytest.approx(lum, rel=1e-12, abs=1e-300)
    if theta >= GRAZING_LIMIT_DEG:
        assert result.grazing_incidence
