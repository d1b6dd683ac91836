"""BRDF models against closed-form values (Spieringhs 2023 Eqs. 3, 15, 17, 18)."""

import numpy as np
import pytest

from rig.brdf_models import MODELS, get_model, mirror_about_normal
from rig.geometry import sph_to_vec

RM1 = {"kd": 0.620, "n": 24.0, "k1": 0.158, "k2": 0.0415, "k3": 0.00133, "k4": 5.47}


def d(theta_deg, phi_deg):
    return sph_to_vec(np.radians(theta_deg), np.radians(phi_deg))


def test_lambert_constant():
    f = get_model("lambert")(d(30, 0), d([0, 45, 80], [0, 90, 200]), {"kd": 0.8})
    np.testing.assert_allclose(f, 0.8 / np.pi)
    assert f.shape == (3,)


def test_modified_phong_peak_and_clamp():
    m = get_model("modified_phong")
    wi = d(40, 10)
    peak = m(wi, mirror_about_normal(wi), {"kd": 0.2, "ks": 0.3, "n": 10})
    assert peak == pytest.approx(0.2 / np.pi + 0.3 * 12 / (2 * np.pi))
    # opposite to the mirror direction the lobe is clamped to zero, not negative or NaN
    far = m(wi, wi * np.array([1, 1, -1]), {"kd": 0.2, "ks": 0.3, "n": 10.5})
    assert far == pytest.approx(0.2 / np.pi)


def test_modified_phong_reciprocal():
    rng = np.random.default_rng(3)
    wi = d(rng.uniform(0, 89, 500), rng.uniform(0, 360, 500))
    wo = d(rng.uniform(0, 89, 500), rng.uniform(0, 360, 500))
    p = {"kd": 0.3, "ks": 0.5, "n": 7}
    m = get_model("modified_phong")
    np.testing.assert_allclose(m(wi, wo, p), m(wo, wi, p), rtol=1e-12)


def test_retrophong_closed_form_at_retro_and_mirror():
    theta_i = 80.0
    c = np.cos(np.radians(theta_i))
    kr = RM1["k1"] * (1 - c) + RM1["k2"]
    ks = RM1["k3"] * np.exp(RM1["k4"] * (1 - c))
    lobe = (RM1["n"] + 2) / (2 * np.pi)
    wi = d(theta_i, 0)
    cos_retro_mirror = np.dot(wi, mirror_about_normal(wi))      # cos of the angle between the two lobes
    f = get_model("retrophong")
    retro = f(wi, wi, RM1)
    mirror = f(wi, mirror_about_normal(wi), RM1)
    assert retro == pytest.approx(RM1["kd"] / np.pi + kr * lobe + ks * lobe * max(cos_retro_mirror, 0) ** 24)
    assert mirror == pytest.approx(RM1["kd"] / np.pi + ks * lobe + kr * lobe * max(cos_retro_mirror, 0) ** 24)
    # paper: retroreflection at θi = 80° close to 1 sr⁻¹ (Sec. 5)
    assert 0.8 < retro < 1.3
    assert kr > ks          # kr > ks except at 85° (text of Sec. 6)


def test_registry_and_unknown_model():
    assert {"lambert", "modified_phong", "retrophong"} <= set(MODELS)
    assert MODELS["retrophong"].param_names == ("kd", "n", "k1", "k2", "k3", "k4")
    with pytest.raises(KeyError, match="unknown BRDF model 'cook'; known: lambert"):
        get_model("cook")


def test_vectorised_broadcast():
    wi = d(np.full((4, 5), 30.0), np.zeros((4, 5)))
    wo = d(np.linspace(0, 80, 5), np.full(5, 180.0))
    out = get_model("retrophong")(wi, wo, RM1)
    assert out.shape == (4, 5) and np.all(np.isfinite(out)) and np.all(out > 0)
