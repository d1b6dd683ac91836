"""BRDF models against closed-form values, their claims and their edge cases.

Sources: Spieringhs 2023 Eqs. 3, 5-11, 15, 17, 18 and Tables 3, 6, 7; Belcour 2014 Eq. 3 (back
vector); Portsmouth 2026 (MRM); Oren & Nayar 1994 Eq. 30; Walter 2007 / Heitz 2014 (GGX, Smith).
Expected values are computed here from the papers' formulas, not from the module's helpers.
"""

import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.integrate import quad

from rig.physics.brdf_models import (
    MODELS,
    albedo,
    back_vector,
    beckmann_ndf,
    get_model,
    ggx_ndf,
    mirror_about_normal,
    schlick,
)
from rig.physics.geometry import sph_to_vec

RM1 = {"kd": 0.620, "n": 24.0, "k1": 0.158, "k2": 0.0415, "k3": 0.00133, "k4": 5.47}

#: Spieringhs 2023 Tables 3, 6 and 7: RM1, RM2, RM3 per model.
PAPER_FITS = {
    "retrophong": [RM1,
                   {"kd": 0.594, "n": 24.0, "k1": 0.0696, "k2": 0.0733, "k3": 6.58e-05, "k4": 8.74},
                   {"kd": 0.701, "n": 68.0, "k1": 0.184, "k2": 1.53e-12, "k3": 0.00570, "k4": 3.40}],
    "oren_nayar": [{"roughness": 0.865, "albedo": 0.268}, {"roughness": 0.705, "albedo": 0.275},
                   {"roughness": 1.26, "albedo": 0.470}],
    "beckmann_retro": [{"kd": 0.796, "alpha": 8.20, "r0": 0.995}, {"kd": 0.822, "alpha": 9.36, "r0": 0.993},
                       {"kd": 0.996, "alpha": 1.61e3, "r0": 1.00}],
    "blinn_retro": [{"kd": 0.919, "alpha_b": 2.77e3, "alpha_r": 7.91e3},
                    {"kd": 0.881, "alpha_b": 2.50e3, "alpha_r": 7.10e3},
                    {"kd": 0.993, "alpha_b": 6.72e3, "alpha_r": 1.65e4}],
    "abc_retro": [{"kd": 0.534, "r0": 0.0472, "a_b": 1.82, "b_b": 13.5, "c_b": 1.51,
                   "a_r": 1.02, "b_r": 0.0775, "c_r": 6.97},
                  {"kd": 0.0303, "r0": 0.140, "a_b": 1.59, "b_b": 32.6, "c_b": 1.08,
                   "a_r": 1.19, "b_r": 0.00779, "c_r": 0.0179},
                  {"kd": 0.747, "r0": 0.00466, "a_b": 6.66, "b_b": 37.8, "c_b": 0.710,
                   "a_r": 3.58, "b_r": 22.9, "c_r": 0.729}],
}

RECIPROCAL = {"lambert", "modified_phong", "oren_nayar", "beckmann_retro", "blinn_retro", "abc_retro",
              "ggx", "mrm", "mrm_diffuse"}

#: Parameter sets under which each energy-conserving claim must hold (modified Phong: kd + ks ≤ 1).
ENERGY_GRIDS = {
    "lambert": [{"kd": 1.0}],
    "modified_phong": [{"kd": kd, "ks": 1.0 - kd, "n": n} for kd in (0.0, 0.5) for n in (0.1, 1.0, 10.0, 300.0)],
    "ggx": [{"roughness": r, "f0": f0} for r in (0.23, 0.48, 0.77, 1.0) for f0 in (0.04, 1.0)],
    "mrm": [{"roughness": r, "f0": f0} for r in (0.23, 0.48, 0.77, 1.0) for f0 in (0.04, 1.0)],
}


def d(theta_deg, phi_deg):
    return sph_to_vec(np.radians(theta_deg), np.radians(phi_deg))


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def schlick_by_hand(u, r0):
    return r0 + (1 - r0) * (1 - u) ** 5


def beckmann_by_hand(c, alpha):          # Spieringhs 2023 Eq. 6
    return np.exp((c**2 - 1) / (alpha**2 * c**2)) / (np.pi * alpha**2 * c**4)


def ggx_d_by_hand(c, alpha):
    return alpha**2 / (np.pi * (c**2 * (alpha**2 - 1) + 1) ** 2)


def smith_lambda_by_hand(c, alpha):      # Heitz 2014 Eq. 72: (−1 + √(1 + α² tan²θ))/2
    return (-1 + np.sqrt(1 + alpha**2 * (1 - c**2) / c**2)) / 2


def cook_torrance_g_by_hand(i, o, h):
    n_h, n_i, n_o, o_h = h[2], i[2], o[2], np.dot(o, h)
    return min(1.0, 2 * n_h * n_o / o_h, 2 * n_h * n_i / o_h)


# --- existing behaviour ---------------------------------------------------------------------

def test_lambert_constant():
    f = get_model("lambert")(d(30, 0), d([0, 45, 80], [0, 90, 200]), {"kd": 0.8})
    np.testing.assert_allclose(f, 0.8 / np.pi)
    assert f.shape == (3,)


def test_modified_phong_peak_and_clamp():
    m = get_model("modified_phong")
    wi = d(40, 10)
    peak = m(wi, mirror_about_normal(wi), {"kd": 0.2, "ks": 0.3, "n": 10})
    assert peak == pytest.approx(0.2 / np.pi + 0.3 * 12 / (2 * np.pi))
    # 100° from the mirror direction the lobe is clamped to zero, not negative or NaN
    far = m(wi, d(60, 10), {"kd": 0.2, "ks": 0.3, "n": 10.5})
    assert far == pytest.approx(0.2 / np.pi)
    # below the horizon there is no reflection at all
    assert m(wi, wi * np.array([1, 1, -1]), {"kd": 0.2, "ks": 0.3, "n": 10.5}) == 0.0


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
    with pytest.raises(KeyError, match="unknown BRDF model 'cook'; known: abc_retro, beckmann_retro"):
        get_model("cook")


def test_vectorised_broadcast():
    wi = d(np.full((4, 5), 30.0), np.zeros((4, 5)))
    wo = d(np.linspace(0, 80, 5), np.full(5, 180.0))
    out = get_model("retrophong")(wi, wo, RM1)
    assert out.shape == (4, 5) and np.all(np.isfinite(out)) and np.all(out > 0)


# --- registry ---------------------------------------------------------------------------------

def test_registry_has_every_model_with_consistent_metadata():
    assert set(MODELS) == {"lambert", "modified_phong", "retrophong", "oren_nayar", "beckmann_retro",
                           "blinn_retro", "abc_retro", "ggx", "mrm", "mrm_diffuse"}
    for name, m in MODELS.items():
        assert m.name == name and m.citation and m.evaluate.__doc__
        assert set(m.typical) == set(m.param_names) and m.log_scale <= set(m.param_names)
        for p, (lo, hi) in m.bounds.items():
            assert lo < hi and lo <= m.typical[p] <= hi, (name, p)
            assert p not in m.log_scale or lo > 0, (name, p)
        wi, wo = d(60, 0), d([0, 30, 60, 60], [0, 180, 180, 0])
        assert np.all(np.isfinite(m(wi, wo, m.typical)))


@pytest.mark.parametrize("name", sorted(PAPER_FITS))
def test_bounds_contain_the_papers_fits(name):
    m = MODELS[name]
    for fit in PAPER_FITS[name]:
        assert tuple(fit) == m.param_names
        for p, v in fit.items():
            lo, hi = m.bounds[p]
            assert lo <= v <= hi, (name, p, v)


def test_stiff_parameters_fit_in_log_space():
    for name, p in [("modified_phong", "n"), ("retrophong", "n"), ("blinn_retro", "alpha_b"),
                    ("blinn_retro", "alpha_r"), ("beckmann_retro", "alpha")]:
        assert p in MODELS[name].log_scale and MODELS[name].bounds[p][1] >= 1e5
    assert "k2" in MODELS["retrophong"].log_scale and MODELS["retrophong"].bounds["k2"][0] <= 1e-13


def test_claims():
    assert {n for n, m in MODELS.items() if m.reciprocal} == RECIPROCAL
    assert {n for n, m in MODELS.items() if m.energy_conserving} == set(ENERGY_GRIDS)


# --- shared pieces --------------------------------------------------------------------------

def test_schlick_and_back_vector():
    assert schlick(1.0, 0.04) == pytest.approx(0.04)
    assert schlick(0.0, 0.04) == pytest.approx(1.0)
    assert schlick(0.5, 0.2) == pytest.approx(0.2 + 0.8 / 32)
    wi = d(50, 30)
    np.testing.assert_allclose(back_vector(wi, wi), [0, 0, 1], atol=1e-15)      # retro: b = n
    np.testing.assert_allclose(back_vector(wi, mirror_about_normal(wi)), wi)    # mirror: b = i


@pytest.mark.parametrize("ndf, alpha", [(ggx_ndf, 0.05), (ggx_ndf, 0.3), (ggx_ndf, 1.0),
                                        (beckmann_ndf, 0.1), (beckmann_ndf, 0.5), (beckmann_ndf, 8.2)])
def test_ndf_is_normalised(ndf, alpha):
    """∫ D(m) cos θm dωm = 1: the projected microfacet area is the macro-surface's."""
    total, _ = quad(lambda mu: 2 * np.pi * ndf(np.array(mu), alpha) * mu, 0, 1, points=[1 / (1 + alpha)], limit=200)
    assert total == pytest.approx(1.0, abs=1e-6)


# --- closed-form values -------------------------------------------------------------------------

def test_oren_nayar_closed_form():
    sigma, rho = 0.865, 0.268                                  # Table 6, RM1
    a = 1 - 0.5 * sigma**2 / (sigma**2 + 0.33)
    b = 0.45 * sigma**2 / (sigma**2 + 0.09)
    m = get_model("oren_nayar")
    p = {"roughness": sigma, "albedo": rho}
    ti, to, dphi = np.radians(60), np.radians(30), np.radians(20)
    expected = rho / np.pi * (a + b * np.cos(dphi) * np.sin(ti) * np.tan(to))
    assert m(d(60, 0), d(30, 20), p) == pytest.approx(expected)
    assert m(d(30, 20), d(60, 0), p) == pytest.approx(expected)
    assert m(d(60, 0), d(75, 200), p) == pytest.approx(rho / np.pi * a)          # cos Δφ < 0
    assert m(d(60, 0), d(0, 0), p) == pytest.approx(rho / np.pi * a)             # tan β = 0
    assert m(d(40, 0), d(40, 0), {"roughness": 0.0, "albedo": rho}) == pytest.approx(rho / np.pi)


def test_ggx_closed_form_at_mirror_and_off_mirror():
    roughness, f0 = 0.3, 0.19
    alpha = roughness ** 2                                      # perceptual roughness, as OpenPBR
    m = get_model("ggx")
    p = {"roughness": roughness, "f0": f0}
    c = np.cos(np.radians(50))                                  # mirror: h = n, i·h = cos θi
    lam = smith_lambda_by_hand(c, alpha)
    expected = schlick_by_hand(c, f0) / (np.pi * alpha**2) / (1 + 2 * lam) / (4 * c * c)
    assert m(d(50, 0), d(50, 180), p) == pytest.approx(expected, rel=1e-12)
    i, o = d(30, 0), d(50, 150)
    h = unit(i + o)
    g2 = 1 / (1 + smith_lambda_by_hand(i[2], alpha) + smith_lambda_by_hand(o[2], alpha))
    expected = schlick_by_hand(np.dot(i, h), f0) * ggx_d_by_hand(h[2], alpha) * g2 / (4 * i[2] * o[2])
    assert m(i, o, p) == pytest.approx(expected, rel=1e-12)


def test_mrm_is_ggx_with_the_view_mirrored():
    rng = np.random.default_rng(7)
    wi = d(rng.uniform(0, 89, 300), rng.uniform(0, 360, 300))
    wo = d(rng.uniform(0, 89, 300), rng.uniform(0, 360, 300))
    p = {"roughness": 0.23, "f0": 0.19}                         # Portsmouth 2026 fit to the yellow tape
    np.testing.assert_allclose(MODELS["mrm"](wi, wo, p), MODELS["ggx"](wi, mirror_about_normal(wo), p),
                               rtol=1e-14)
    # at exact retroreflection the back vector is n: the GGX mirror value, D = 1/(πα²)
    c = np.cos(np.radians(50))
    alpha = 0.23 ** 2                                         # perceptual roughness 0.23
    lam = smith_lambda_by_hand(c, alpha)
    expected = schlick_by_hand(c, 0.19) / (np.pi * alpha**2) / (1 + 2 * lam) / (4 * c * c)
    assert MODELS["mrm"](d(50, 70), d(50, 70), p) == pytest.approx(expected, rel=1e-12)
    pd = {"kd": 0.4, **p}
    np.testing.assert_allclose(MODELS["mrm_diffuse"](wi, wo, pd), 0.4 / np.pi + MODELS["mrm"](wi, wo, p))


@pytest.mark.parametrize("alpha", [0.3, 8.20])                # 8.20: Table 7, RM1
def test_beckmann_retro_closed_form_at_retro_and_mirror(alpha):
    kd, r0 = 0.796, 0.6
    p = {"kd": kd, "alpha": alpha, "r0": r0}
    m = get_model("beckmann_retro")
    i = d(60, 25)
    c = i[2]
    # retro o = i: h = i (F(1) = R0, D(cos θi)); b = n (F(cos θi), D(1) = 1/(πα²)); G = min(1, 2cos²θi)
    g = cook_torrance_g_by_hand(i, i, i)
    assert g == pytest.approx(min(1, 2 * c * c))
    expected = kd / np.pi + (r0 * beckmann_by_hand(c, alpha)
                             + schlick_by_hand(c, r0) / (np.pi * alpha**2)) * g / (4 * c * c)
    assert m(i, i, p) == pytest.approx(expected, rel=1e-12)
    # mirror o = i_s: h = n (F(cos θi), D(1)); b = i (F(1) = R0, D(cos θi)); G = 1
    o = mirror_about_normal(i)
    expected = kd / np.pi + (schlick_by_hand(c, r0) / (np.pi * alpha**2)
                             + r0 * beckmann_by_hand(c, alpha)) / (4 * c * c)
    assert m(i, o, p) == pytest.approx(expected, rel=1e-12)
    # a generic pair, with h and b built by hand (Belcour 2014 Eq. 3)
    i, o = d(35, 0), d(55, 120)
    h, b = unit(i + o), unit(i + o * [-1, -1, 1])
    expected = kd / np.pi + cook_torrance_g_by_hand(i, o, h) / (4 * i[2] * o[2]) * (
        schlick_by_hand(np.dot(i, h), r0) * beckmann_by_hand(h[2], alpha)
        + schlick_by_hand(np.dot(i, b), r0) * beckmann_by_hand(b[2], alpha))
    assert m(i, o, p) == pytest.approx(expected, rel=1e-12)


def test_blinn_retro_closed_form():
    p = {"kd": 0.5, "alpha_b": 20.0, "alpha_r": 50.0}
    m = get_model("blinn_retro")
    i = d(70, 40)
    c = i[2]
    # α_r belongs to the forward lobe (h·n)^α_r, α_b to the retro lobe (b·n)^α_b
    assert m(i, i, p) == pytest.approx(0.5 / np.pi + c**50 + 1.0)
    assert m(i, mirror_about_normal(i), p) == pytest.approx(0.5 / np.pi + 1.0 + c**20)
    i, o = d(35, 0), d(30, 20)
    h, b = unit(i + o), unit(i + o * [-1, -1, 1])
    assert m(i, o, p) == pytest.approx(0.5 / np.pi + h[2] ** 50 + b[2] ** 20, rel=1e-12)


def test_abc_retro_closed_form():
    p = PAPER_FITS["abc_retro"][0]                              # Table 7, RM1
    m = get_model("abc_retro")

    def abc(cos, a, b, c):                                      # Spieringhs 2023 Eq. 10
        return a / (1 + b * (1 - cos)) ** c

    i = d(80, 0)
    c, r0 = i[2], p["r0"]
    fwd_at = lambda cos: abc(cos, p["a_r"], p["b_r"], p["c_r"])
    retro_at = lambda cos: abc(cos, p["a_b"], p["b_b"], p["c_b"])
    # retro: h = i → F(1)·ABC_r(cos θi); b = n → F(cos θi)·A_b
    assert m(i, i, p) == pytest.approx(p["kd"] / np.pi + r0 * fwd_at(c) + schlick_by_hand(c, r0) * p["a_b"])
    # mirror: h = n → F(cos θi)·A_r; b = i → F(1)·ABC_b(cos θi)
    assert m(i, mirror_about_normal(i), p) == pytest.approx(
        p["kd"] / np.pi + schlick_by_hand(c, r0) * p["a_r"] + r0 * retro_at(c))


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
