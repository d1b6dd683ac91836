"""Road-lighting quantities of a simulated RetroPhong sample, end to end: on the reduced campaign's run on
the simulated rig (the shared `e2e_run`), `rig export --format road --model retrophong` fits the model and
writes road.json, and its R_L, Qd, r-table, Q0 and S1 agree with the same quantities computed here directly from
the simulated truth (other quadratures, no rig code but the model's formula) within their stated u."""

import json

import numpy as np
import pytest

from repo_paths import E2E_CAMPAIGN
from rig.cli.main import main
from rig.config.campaign import load_campaign
from rig.physics.brdf_models import get_model
from rig.physics.geometry import sph_to_vec

BETA = [0, 2, 5, 10, 15, 20, 25, 30, 35, 40, 45, 60, 75, 90, 105, 120, 135, 150, 165, 180]
TAN_GAMMA = [*np.arange(0, 2.01, 0.25), *np.arange(2.5, 12.01, 0.5)]


@pytest.fixture(scope="module")
def exported(e2e_run, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("road")
    assert main(["export", str(e2e_run), "--format", "road", "--model", "retrophong",
                 "--out", str(tmp / "road.json")]) == 0
    spec = load_campaign(E2E_CAMPAIGN).sample.simulated_brdf
    model = get_model(spec.model)

    def truth(theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg):
        wi = sph_to_vec(np.radians(theta_i_deg), np.radians(phi_i_deg))
        wo = sph_to_vec(np.radians(theta_o_deg), np.radians(phi_o_deg))
        return model(wi, wo, spec.params)
    return json.loads((tmp / "road.json").read_text()), truth


def test_r_l_at_the_30_m_geometry(exported):
    road, truth = exported
    expected = 1e3 * float(truth(88.76, 0.0, 87.71, 0.0)) * np.cos(np.radians(88.76))
    assert expected == pytest.approx(21.8, abs=0.1)                 # Spieringhs et al. 2023's RM1
    assert abs(road["R_L_mcd_m2_lx"] - expected) <= 2 * road["u_R_L_mcd_m2_lx"]
    assert "R_L" in road["extrapolated"]                            # θi 88.76° lies beyond the rig's 85°


def test_qd_under_uniform_sky(exported):
    road, truth = exported
    n_t, n_p = 400, 720                                             # midpoint rule in θi and φi
    t = (np.arange(n_t) + 0.5) * (np.pi / 2) / n_t
    p = (np.arange(n_p) + 0.5) * 2 * np.pi / n_p
    tt, pp = np.meshgrid(t, p, indexing="ij")
    f = truth(np.degrees(tt), np.degrees(pp), 87.71, 0.0)
    qd = 1e3 / np.pi * np.sum(f * np.cos(tt) * np.sin(tt)) * (np.pi / 2 / n_t) * (2 * np.pi / n_p)
    assert abs(road["Qd_mcd_m2_lx"] - qd) <= 2 * road["u_Qd_mcd_m2_lx"]


def test_r_table_grid_q0_and_s1(exported):
    road, truth = exported
    table = road["r_table"]
    assert table["beta_deg"] == pytest.approx(BETA, abs=0) and table["tan_gamma"] == pytest.approx(TAN_GAMMA, abs=0)
    r = np.array(table["r_x1e4"])
    assert r.shape == (29, 20)
    gamma = np.arctan(np.array(TAN_GAMMA))[:, None]
    expected = 1e4 * truth(np.degrees(gamma), 180.0 - np.array(BETA)[None, :], 89.0, 0.0) * np.cos(gamma) ** 3
    u = np.array(road["u_r_x1e4"]) if "u_r_x1e4" in road else None
    within = np.abs(r - expected) <= (2 * u if u is not None else 0.1 * expected)
    assert within.mean() >= 0.9, f"{within.mean():.2f} of the r-table within 2u"
    s1 = expected[8, 0] / expected[0, 0]                          # tan γ = 2 and 0 at β = 0
    assert abs(road["S1"] - s1) <= 2 * road.get("u_S1", 0.1 * s1)
    assert road["Q0"] > 0
