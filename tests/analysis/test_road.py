"""Road-lighting quantities at the standard geometries (rig.analysis.road) against values computed here
independently: from the physical positions of lamp, eye and luminaire, with other quadratures (a midpoint
rule in θ, and one in tan γ), the closed forms of a Lambertian and the worked example of docs/road-lighting.md.

The truth is the simulated sample of tests/campaigns/e2e-reduced.yaml (RetroPhong, Spieringhs et al.
2023 Table 7 RM1), predicted with u = 2 % of f and flagged extrapolated where the rig cannot measure:
θi > 85° or within 5° of retroreflection (the lamp's occlusion cone).
"""

import json
from collections.abc import Callable

import numpy as np
import pytest

from repo_paths import E2E_CAMPAIGN
from rig.analysis import road
from rig.analysis.prediction import Prediction
from rig.config.campaign import load_campaign
from rig.physics.brdf_models import get_model
from rig.physics.geometry import angle_between, sph_to_vec

REL_U = 0.02
MAX_THETA_I_DEG = 85.0
OCCLUSION_DEG = 5.0
#: EN 1436 value of RM1 at the 30 m geometry, from Spieringhs et al. 2023's RetroPhong fit (issue 14).
RM1_R_L_MCD = 21.8
#: The r-table's β, degrees (CIE 144 / IES r-tables).
STANDARD_BETA = [0, 2, 5, 10, 15, 20, 25, 30, 35, 40, 45, 60, 75, 90, 105, 120, 135, 150, 165, 180]


def _unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _measurable(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    return (wi[..., 2] >= np.cos(np.radians(MAX_THETA_I_DEG))) & (np.degrees(angle_between(wi, wo)) >= OCCLUSION_DEG)


class TruthPredictor:
    """A closed-form BRDF f(ωi, ωo) with u = rel_u · f, extrapolated outside `_measurable`."""

    def __init__(self, brdf: Callable[[np.ndarray, np.ndarray], np.ndarray], rel_u: float = REL_U):
        self.brdf, self.rel_u, self.method = brdf, rel_u, "closed-form truth"

    def predict(self, theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg) -> Prediction:
        wi = sph_to_vec(np.radians(theta_i_deg), np.radians(phi_i_deg))
        wo = sph_to_vec(np.radians(theta_o_deg), np.radians(phi_o_deg))
        f = self.brdf(wi, wo)
        return Prediction(f, self.rel_u * f, ~_measurable(wi, wo))


def model_brdf(name: str, params) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    model = get_model(name)
    return lambda wi, wo: model(wi, wo, params)


@pytest.fixture(scope="module")
def rm1_brdf():
    brdf = load_campaign(E2E_CAMPAIGN).sample.simulated_brdf
    assert brdf is not None
    return model_brdf(brdf.model, brdf.params)


@pytest.fixture(scope="module")
def rm1(rm1_brdf):
    return road.road_quantities(TruthPredictor(rm1_brdf))


def _cot(deg: float) -> float:
    return 1.0 / np.tan(np.radians(deg))


def test_r_l_from_the_30_m_geometry(rm1, rm1_brdf):
    # headlamp 0.65 m and eye 1.2 m above the line, 30 m away on the same side (ASTM E1710-18 §5.5)
    wi, wo = _unit([-30.0, 0.0, 0.65]), _unit([-30.0, 0.0, 1.2])
    expected = 1e3 * rm1_brdf(wi, wo) * wi[2]                  # L/E⊥ = f · cos θi
    assert rm1.u_R_L_mcd_m2_lx == pytest.approx(REL_U * rm1.R_L_mcd_m2_lx, rel=1e-12)
    # the standard's rounded angles (88.76°, 87.71°) move R_L by 0.1 %, far inside u
    assert abs(rm1.R_L_mcd_m2_lx - expected) < 0.1 * rm1.u_R_L_mcd_m2_lx
    assert rm1.R_L_mcd_m2_lx == pytest.approx(RM1_R_L_MCD, abs=0.05)
    assert rm1.R_L_extrapolated


def _midpoint(n: int, lo: float, hi: float) -> tuple[np.ndarray, float]:
    h = (hi - lo) / n
    return lo + (np.arange(n) + 0.5) * h, h


def test_qd_against_a_midpoint_rule_in_theta(rm1, rm1_brdf):
    theta, d_theta = _midpoint(720, 0.0, np.pi / 2)
    phi, d_phi = _midpoint(1440, 0.0, 2 * np.pi)
    wi = sph_to_vec(theta[:, None], phi[None, :])
    wo = sph_to_vec(np.radians(87.71), np.radians(0.0))
    qd = 1e3 / np.pi * np.sum(rm1_brdf(wi, wo) * (np.cos(theta) * np.sin(theta))[:, None]) * d_theta * d_phi
    assert rm1.Qd.u == pytest.approx(REL_U * rm1.Qd.value, rel=1e-12)     # fully correlated: u adds up
    assert abs(rm1.Qd.value - qd) < 0.01 * rm1.Qd.u
    assert 0.0 < rm1.Qd.extrapolated_share < 0.05


def _r_table_directions() -> tuple[np.ndarray, np.ndarray]:
    """(ωi, ωo) of every cell from positions: eye 1.5 m high looking 1° down at the point (on −x), luminaire
    at height h whose foot is tan γ·h from the point, in the plan direction β from +x, so that the angle
    between observer→point (+x) and luminaire→point is 180° − β (β = 0: luminaire beyond the point)."""
    eye = np.array([-1.5 * _cot(1.0), 0.0, 1.5])
    tan_gamma = np.array([0, .25, .5, .75, 1, 1.25, 1.5, 1.75, 2, 2.5, 3, 3.5, 4, 4.5, 5, 5.5, 6, 6.5, 7, 7.5,
                          8, 8.5, 9, 9.5, 10, 10.5, 11, 11.5, 12])
    beta = np.radians(STANDARD_BETA)
    h = 10.0
    lum = np.stack(np.broadcast_arrays(h * tan_gamma[:, None] * np.cos(beta), h * tan_gamma[:, None] * np.sin(beta),
                                       h), axis=-1)
    return _unit(lum), _unit(eye)


def test_standard_grid():
    assert road.BETA_DEG.shape == (20,) and np.allclose(road.BETA_DEG, STANDARD_BETA, rtol=0, atol=1e-12)
    assert road.TAN_GAMMA.shape == (29,)
    assert np.allclose(road.TAN_GAMMA, np.r_[np.arange(9) * 0.25, 2.5 + np.arange(20) * 0.5], rtol=0, atol=1e-12)


def test_r_table_s1_and_flags_from_positions(rm1, rm1_brdf):
    wi, wo = _r_table_directions()
    r = 1e4 * rm1_brdf(wi, wo) * wi[..., 2] ** 3               # r = q cos³γ
    assert rm1.r_x1e4.shape == rm1.u_r_x1e4.shape == rm1.r_extrapolated.shape == (29, 20)
    assert np.allclose(rm1.r_x1e4, r, rtol=1e-9, atol=0)
    assert np.allclose(rm1.u_r_x1e4, REL_U * r, rtol=1e-9, atol=0)
    assert np.array_equal(rm1.r_extrapolated, ~_measurable(wi, wo))
    s1 = r[8, 0] / r[0, 0]                                      # r(β 0, tan γ 2) / r(0, 0)
    assert rm1.S1 == pytest.approx(s1, rel=1e-9)
    assert rm1.u_S1 == pytest.approx(2 * REL_U * s1, rel=1e-9)   # correlation −1 for a ratio: relative u's add


def test_q0_against_the_tan_gamma_form(rm1, rm1_brdf):
    # Q0 = (1/Ω0) ∬ r tan γ d(tan γ) dβ over tan γ ≤ 12 and both sides (docs/road-lighting.md)
    t, dt = _midpoint(2400, 0.0, 12.0)
    phi, d_phi = _midpoint(720, 0.0, 2 * np.pi)
    wi = sph_to_vec(np.arctan(t)[:, None], phi[None, :])
    wo = sph_to_vec(np.radians(89.0), np.radians(0.0))
    r = rm1_brdf(wi, wo) * wi[..., 2] ** 3
    omega0 = 2 * np.pi * (1 - 1 / np.sqrt(1 + 12.0**2))
    q0 = np.sum(r * t[:, None]) * dt * d_phi / omega0
    assert rm1.Q0.u == pytest.approx(REL_U * rm1.Q0.value, rel=1e-12)
    assert abs(rm1.Q0.value - q0) < 0.01 * rm1.Q0.u
    assert 0.0 < rm1.Q0.extrapolated_share < 0.05


def test_observer_azimuth_does_not_matter_for_an_isotropic_sample(rm1, rm1_brdf):
    turned = road.road_quantities(TruthPredictor(rm1_brdf), phi_o_deg=123.0)
    assert turned.R_L_mcd_m2_lx == pytest.approx(rm1.R_L_mcd_m2_lx, rel=1e-9)
    assert turned.Qd.value == pytest.approx(rm1.Qd.value, rel=1e-6)
    assert turned.Q0.value == pytest.approx(rm1.Q0.value, rel=1e-6)
    assert np.allclose(turned.r_x1e4, rm1.r_x1e4, rtol=1e-9, atol=0)


def test_lambertian_closed_forms():
    rho = 0.5
    q = road.road_quantities(TruthPredictor(model_brdf("lambert", {"kd": rho})))
    assert q.Qd.value == pytest.approx(1e3 * rho / np.pi, rel=1e-10)              # 159.15 mcd·m⁻²·lx⁻¹
    assert q.R_L_mcd_m2_lx == pytest.approx(1e3 * rho / np.pi * np.cos(np.radians(88.76)), rel=1e-12)
    assert q.Q0.value == pytest.approx(rho / np.pi, rel=1e-10)
    cos3 = (1 / np.sqrt(1 + road.TAN_GAMMA**2))[:, None] ** 3
    assert np.allclose(q.r_x1e4, 1e4 * rho / np.pi * cos3 * np.ones(20), rtol=1e-12, atol=0)
    assert q.S1 == pytest.approx(5 ** -1.5, rel=1e-12)                              # cos³(atan 2)


def _worked_example(wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """f = 9 sr⁻¹ for a marking at grazing light; 0.03 + 0.0675 tan²γ for a road surface lit from above."""
    tan2 = (1 - wi[..., 2] ** 2) / np.maximum(wi[..., 2], 1e-12) ** 2
    return np.where(wi[..., 2] < np.cos(np.radians(88.0)), 9.0, 0.03 + 0.0675 * tan2)


def test_worked_example_and_classes(tmp_path):
    q = road.road_quantities(TruthPredictor(_worked_example, rel_u=0.01))
    assert q.R_L_mcd_m2_lx == pytest.approx(195.0, abs=0.5)
    assert q.r_x1e4[0, 0] == pytest.approx(300.0, rel=1e-9) and q.r_x1e4[8, 0] == pytest.approx(268.3, abs=0.05)
    assert q.S1 == pytest.approx(0.894, abs=5e-4)
    data = json.loads(road.export_road(TruthPredictor(_worked_example, rel_u=0.01), tmp_path / "road.json")
                      .read_text(encoding="utf-8"))
    assert data["marking_classes"]["R_L"] == "R3" and data["marking_classes_within_k2"]["R_L"] == ["R3"]
    assert data["surface_classes"] == {"R": "R3", "C": "C2", "N": "N3"}
    assert data["standard_Q0"] == {"R": 0.07, "C": 0.07, "N": 0.07}


def test_class_limits_are_lower_bounds():
    limits = road.S1_CLASSES["R"]
    assert [road.classify(s, limits) for s in (0.0, 0.4199, 0.42, 0.85, 1.3499, 1.35, 9.0)] == \
        ["R1", "R1", "R2", "R3", "R3", "R4", "R4"]
    assert road.classes_within(0.80, 0.03, limits) == ["R2", "R3"]         # 0.80 ± 0.06 crosses 0.85
    assert road.classes_within(0.10, 0.20, limits) == ["R1", "R2"]         # never below the first class


def test_json_keys_shapes_and_no_overwrite(rm1_brdf, tmp_path):
    out = road.export_road(TruthPredictor(rm1_brdf), tmp_path / "road.json")
    data = json.loads(out.read_text(encoding="utf-8"))
    assert list(data)[:10] == ["R_L_mcd_m2_lx", "u_R_L_mcd_m2_lx", "Qd_mcd_m2_lx", "u_Qd_mcd_m2_lx", "r_table",
                               "Q0", "S1", "extrapolated", "u_Q0", "u_S1"]
    table = data["r_table"]
    assert len(table["beta_deg"]) == 20 and len(table["tan_gamma"]) == 29
    assert np.shape(table["r_x1e4"]) == np.shape(table["u_r_x1e4"]) == np.shape(table["extrapolated"]) == (29, 20)
    assert data["method"] == "closed-form truth"
    with pytest.raises(FileExistsError):
        road.export_road(TruthPredictor(rm1_brdf), out)


def test_extrapolation_note_names_the_cells(rm1):
    note = road.extrapolation_note(rm1)
    # θi > 85° ⇔ tan γ ≥ 11.5; within 5° of retroreflection at θo = 89°: β = 180°, γ > 84° ⇔ tan γ ≥ 10
    assert "R_L (θi 88.76°, θo 87.71°, same azimuth): extrapolated." in note
    assert "43 of 580 cells extrapolated: tan γ 10–11 at β 180; tan γ 11.5–12 at every β." in note
    assert "S1: its cells r(0°, 0) and r(0°, 2) are within the measured domain." in note
    assert f"Qd: {100 * rm1.Qd.extrapolated_share:.1f} % of the integral" in note


def test_extrapolation_note_when_everything_is_measured():
    class Measured(TruthPredictor):
        def predict(self, *angles):
            p = super().predict(*angles)
            return Prediction(p.brdf_per_sr, p.u_brdf_per_sr, np.zeros_like(p.extrapolated))

    q = road.road_quantities(Measured(model_brdf("lambert", {"kd": 0.5})), n=16)
    note = road.extrapolation_note(q)
    assert "within the measured domain." in note and "0 of 580 cells extrapolated." in note
    assert "Qd: 0.0 %" in note and not q.R_L_extrapolated
