"""BRDF models' properties over all directions: reciprocity, energy (albedo), where the lobes are, finiteness
at the horizon and at the corners of the bounds (sources: the top of test_brdf_models.py)."""

import itertools

import numpy as np
import pytest
from brdf_cases import (
    ENERGY_GRIDS,
    PAPER_FITS,
    RECIPROCAL,
    RM1,
    d,
)
from hypothesis import given, settings
from hypothesis import strategies as st

from rig.physics.brdf_models import (
    MODELS,
    albedo,
    mirror_about_normal,
)

# --- reciprocity ------------------------------------------------------------------------------

def _pairs(n=400, seed=11):
    """Random above-horizon pairs, half of them within a few degrees of the retro or mirror direction."""
    rng = np.random.default_rng(seed)
    wi = d(rng.uniform(0, 88, n), rng.uniform(0, 360, n))
    wo = d(rng.uniform(0, 88, n), rng.uniform(0, 360, n))
    near = wi * np.where(rng.random((n, 1)) < 0.5, 1.0, [-1.0, -1.0, 1.0]) + rng.normal(0, 0.03, (n, 3))
    wo = np.where(rng.random((n, 1)) < 0.5, wo, near / np.linalg.norm(near, axis=-1, keepdims=True))
    keep = wo[:, 2] > 0.02
    return wi[keep], wo[keep]


@pytest.mark.parametrize("name", sorted(RECIPROCAL))
def test_reciprocity(name):
    m = MODELS[name]
    wi, wo = _pairs()
    for p in [m.typical] + PAPER_FITS.get(name, []):
        f = m(wi, wo, p)
        assert np.ptp(f) > 0 or name == "lambert"
        np.testing.assert_allclose(f, m(wo, wi, p), rtol=1e-9, atol=1e-300)


def test_retrophong_is_not_reciprocal_and_does_not_claim_it():
    m = MODELS["retrophong"]
    assert not m.reciprocal and not m.energy_conserving
    i, o = d(80, 0), d(60, 0)                                   # 20° off retro: kr(80°) ≠ kr(60°)
    assert abs(m(i, o, RM1) / m(o, i, RM1) - 1) > 0.1


# --- energy -----------------------------------------------------------------------------------

THETA_I = np.array([0.0, 30.0, 60.0, 80.0, 85.0, 89.0])


@pytest.mark.parametrize("name", sorted(ENERGY_GRIDS))
def test_albedo_at_most_one_where_claimed(name):
    for p in ENERGY_GRIDS[name]:
        a = albedo(MODELS[name], p, THETA_I)
        assert np.all(a <= 1 + 1e-3) and np.all(a >= 0), (p, a)


def test_albedo_quadrature_closed_forms():
    assert albedo(MODELS["lambert"], {"kd": 0.7}, THETA_I) == pytest.approx(0.7, abs=1e-12)
    # (n+2)/(2π) cos^n about the mirror direction integrates to 1 at normal incidence
    for n in (1.0, 24.0, 1000.0):
        assert albedo(MODELS["modified_phong"], {"kd": 0.2, "ks": 0.5, "n": n}, 0.0) == pytest.approx(0.7, abs=1e-4)
    assert albedo(MODELS["ggx"], {"roughness": 0.5, "f0": 1.0}, [[0.0, 30.0]]).shape == (1, 2)
    # GGX with α = 1: D = 1/π and G2/(4 cos θi cos θo) = 1/(2(1 + cos θo)) at θi = 0, so E = 1 − ln 2
    assert albedo(MODELS["ggx"], {"roughness": 1.0, "f0": 1.0}, 0.0) == pytest.approx(1 - np.log(2), abs=1e-6)


def test_oren_nayar_albedo_exceeds_rho_near_grazing_so_no_energy_claim():
    a = albedo(MODELS["oren_nayar"], {"roughness": 0.2, "albedo": 1.0}, [0.0, 89.0])
    assert a[0] < 1 < a[1]


@pytest.mark.parametrize("roughness, f0", [(0.32, 0.04), (0.23, 0.19), (0.5, 1.0), (1.0, 0.5)])
def test_mrm_albedo_equals_ggx_albedo(roughness, f0):
    """Portsmouth 2026: o ↦ o' keeps dω and cos θo, so MRM and GGX reflect the same energy."""
    p = {"roughness": roughness, "f0": f0}
    theta = np.array([0.0, 30.0, 60.0, 80.0, 85.0])
    ggx_albedo = albedo(MODELS["ggx"], p, theta, n=128)
    mrm_albedo = albedo(MODELS["mrm"], p, theta, n=97)          # another grid: agreement is not by symmetry
    np.testing.assert_allclose(mrm_albedo, ggx_albedo, atol=1e-3)
    np.testing.assert_allclose(albedo(MODELS["mrm_diffuse"], {"kd": 0.3, **p}, theta, n=97),
                               0.3 + mrm_albedo, atol=1e-12)


# --- where the lobes are ----------------------------------------------------------------------

def test_mrm_peaks_at_retroreflection_and_ggx_at_the_mirror():
    p = {"roughness": 0.23, "f0": 0.19}
    t = np.arange(-89.0, 89.01, 0.25)                          # signed θo in the plane of incidence
    wo = d(np.abs(t), np.where(t >= 0, 0.0, 180.0))
    for theta_i in (0.0, 20.0, 40.0):                          # beyond, 1/cos θo moves the maximum to grazing
        wi = d(theta_i, 0.0)
        assert t[np.argmax(MODELS["ggx"](wi, wo, p))] == pytest.approx(-theta_i, abs=3.5)
        assert t[np.argmax(MODELS["mrm"](wi, wo, p))] == pytest.approx(theta_i, abs=3.5)
    for theta_i in (20.0, 40.0, 60.0, 80.0):
        wi = d(theta_i, 0.0)
        retro, mirror = wi, mirror_about_normal(wi)
        assert MODELS["mrm"](wi, retro, p) > 5 * MODELS["mrm"](wi, mirror, p)
        assert MODELS["ggx"](wi, mirror, p) > 5 * MODELS["ggx"](wi, retro, p)


# --- finiteness and the horizon -----------------------------------------------------------------

def _param_strategy(m):
    def one(name):
        lo, hi = m.bounds[name]
        if name in m.log_scale:
            return st.floats(np.log(lo), np.log(hi)).map(lambda x: float(np.clip(np.exp(x), lo, hi)))
        return st.floats(lo, hi)
    return st.fixed_dictionaries({name: one(name) for name in m.param_names})


def _direction(cos_t, phi):
    s = np.sqrt(max(0.0, 1.0 - cos_t**2))
    return np.array([s * np.cos(phi), s * np.sin(phi), cos_t])


SPECIAL_COS = [0.0, 5e-324, 1e-300, 1e-12, 1e-6, 1.0, -1e-300, -0.3, -1.0]
cosines = st.one_of(st.sampled_from(SPECIAL_COS), st.floats(-1.0, 1.0))
relations = st.sampled_from(["free", "retro", "mirror", "opposite"])


@pytest.mark.parametrize("name", sorted(MODELS))
@settings(max_examples=60, deadline=None)
@given(data=st.data(), ci=cosines, co=cosines, phi_i=st.floats(0, 2 * np.pi), phi_o=st.floats(0, 2 * np.pi),
       relation=relations)
def test_finite_everywhere_and_zero_below_horizon(name, data, ci, co, phi_i, phi_o, relation):
    m = MODELS[name]
    p = data.draw(_param_strategy(m))
    wi = _direction(ci, phi_i)
    wo = {"free": _direction(co, phi_o), "retro": wi, "mirror": mirror_about_normal(wi), "opposite": -wi}[relation]
    f = np.asarray(m(wi, wo, p))
    assert np.isfinite(f) and f >= 0
    if wi[2] <= 0 or wo[2] <= 0:
        assert f == 0


@pytest.mark.parametrize("name", sorted(MODELS))
def test_finite_at_the_corners_of_the_bounds(name):
    """Every combination of bound values at normal, retro, mirror and both-grazing geometries."""
    m = MODELS[name]
    wi = np.array([[0, 0, 1.0], d(89.9999, 0), d(60, 0), [1.0, 0, 1e-300]])
    wo = np.stack([wi, mirror_about_normal(wi), d([89.9999] * 4, [180, 0, 90, 180])], axis=1)
    for corner in itertools.product(*m.bounds.values()):
        f = m(wi[:, None, :], wo, dict(zip(m.param_names, corner)))
        assert f.shape == (4, 3) and np.all(np.isfinite(f)) and np.all(f >= 0), corner
