"""The static grain's share of the ROI texture, estimated from the ROI block patterns of views that see the same
sample area (issue 34): on the simulated sample, rendered with its static and glint factors apart, it recovers
the static share; a glint-only or static-only sample gives about 0 or 1."""

import numpy as np
import pytest

from repo_paths import E2E_CAMPAIGN
from rig.config.campaign import load_campaign
from rig.config.rigfile import RigConfig, SimulationConfig, camera_optics
from rig.core.values import Window
from rig.physics.geometry import LAMP_DIRECTION_GCS, sample_frame
from rig.physics.roi import roi_statistics
from rig.physics.static_texture import MIN_PAIRS, StaticTexture, grid_map, half_vector
from rig.planning.plan import build_plan
from rig.simulators.camera import lit_view
from rig.simulators.texture import GlintTexture, ValueNoiseTexture

ROI_PX = 70


def rendered_views(sim: SimulationConfig):
    """Per planned point of the reduced end-to-end campaign: the ROI's static and glint factors (the simulated
    camera's geometry and texture), its motors and its angles."""
    campaign, rig = load_campaign(E2E_CAMPAIGN), RigConfig(simulation=sim)
    optics = camera_optics(rig)
    roi = Window.centred(optics.width_px, optics.height_px, ROI_PX, ROI_PX)
    static, glint = ValueNoiseTexture.from_config(sim), GlintTexture.from_config(sim)
    for p in build_plan(campaign, rig).points:
        alpha, beta, a, b = np.radians(p.motors_deg)
        frame = sample_frame(alpha, beta)
        lit, xy, wo = lit_view(optics, a, b, roi, frame, rig.geometry.spot_diameter_m / 2)
        if len(xy) == lit.size:
            s = static(xy[:, 0], xy[:, 1]).reshape(ROI_PX, ROI_PX)
            g = glint(xy[:, 0], xy[:, 1], LAMP_DIRECTION_GCS @ frame, wo).reshape(ROI_PX, ROI_PX)
            yield p, s, g


def estimate(sim: SimulationConfig) -> tuple[StaticTexture, float]:
    """The estimate from the patterns of the rendered ROIs, and the truth: the static factor's share of the
    block patterns' power."""
    texture, static_power, power = StaticTexture(), 0.0, 0.0
    for p, s, g in rendered_views(sim):
        pattern = roi_statistics(s * g, np.zeros_like(s)).pattern
        assert pattern is not None
        texture.observe(p.point_id, pattern, grid_map(p.motors_deg),
                        half_vector(p.theta_i_deg, p.phi_i_deg, p.theta_o_deg, p.phi_o_deg))
        static_power += float(np.sum(roi_statistics(s, np.zeros_like(s)).pattern ** 2))
        power += float(np.sum(pattern ** 2))
    return texture, static_power / power


@pytest.mark.parametrize("seed", [1, 2])
def test_the_pairs_of_views_recover_the_static_share(seed):
    texture, truth = estimate(SimulationConfig(seed=seed))
    assert texture.pairs >= 100
    assert 0.15 < truth < 0.35                                  # about a quarter (docs/uncertainty.md)
    assert texture.share == pytest.approx(truth, abs=0.06)


def test_no_glints_all_static_no_grain_none():
    only_static, _ = estimate(SimulationConfig(seed=3, glint_contrast=0.0))
    only_glints, _ = estimate(SimulationConfig(seed=3, texture_contrast=0.0))
    assert only_static.share > 0.85 and only_glints.share < 0.05


def test_too_few_pairs_move_nothing():
    texture = StaticTexture()
    pattern = np.ones((7, 7))
    for k in range(5):
        texture.observe(f"p{k}", pattern, np.eye(2), half_vector(10.0 * k, 0.0, 0.0, 0.0))
    assert 0 < texture.pairs < MIN_PAIRS and texture.share == 0.0


def test_overlapping_footprints_share_their_grain():
    """A view along the normal and one at 60° (its footprint twice as long, holding the first): each shares
    with the other the overlap over the geometric mean of their areas, 1/√2."""
    texture = StaticTexture()
    texture.observe("a", np.ones((7, 7)), np.eye(2), half_vector(0, 0, 0, 0))
    tilted = np.diag([2.0, 1.0])
    assert texture.common_fraction("b", tilted) == pytest.approx(1 / np.sqrt(2), abs=0.02)
