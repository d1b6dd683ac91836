"""BRDF models against closed-form values, their claims and their edge cases.

Sources: Spieringhs 2023 Eqs. 3, 5-11, 15, 17, 18 and Tables 3, 6, 7; Belcour 2014 Eq. 3 (back
vector); Portsmouth 2026 (MRM); Oren & Nayar 1994 Eq. 30; Walter 2007 / Heitz 2014 (GGX, Smith).
Expected values are computed here from the papers' formulas, not from the module's helpers.
"""

import numpy as np
import pytest
from brdf_cases import (
    ENERGY_GRIDS,
    PAPER_FITS,
    RECIPROCAL,
    RM1,
    beckmann_by_hand,
    cook_torrance_g_by_hand,
    d,
    ggx_d_by_hand,
    schlick_by_hand,
    smith_lambda_by_hand,
    unit,
)
from scipy.integrate import quad

from rig.physics.brdf_models import (
    MODELS,
    back_vector,
    beckmann_ndf,
    get_model,
    ggx_ndf,
    mirror_about_normal,
    schlick,
)

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

    def fwd_at(cos: float) -> float:
        return abc(cos, p["a_r"], p["b_r"], p["c_r"])

    def retro_at(cos: float) -> float:
        return abc(cos, p["a_b"], p["b_b"], p["c_b"])

    # retro: h = i → F(1)·ABC_r(cos θi); b = n → F(cos θi)·A_b
    assert m(i, i, p) == pytest.approx(p["kd"] / np.pi + r0 * fwd_at(c) + schlick_by_hand(c, r0) * p["a_b"])
    # mirror: h = n → F(cos θi)·A_r; b = i → F(1)·ABC_b(cos θi)
    assert m(i, mirror_about_normal(i), p) == pytest.approx(
        p["kd"] / np.pi + schlick_by_hand(c, r0) * p["a_r"] + r0 * retro_at(c))
