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
                        half_vector(p.theta_i_deg, p.phi_i_deg, p.theta_o_deg, p.phi_o_deg), 1e-6)
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
        texture.observe(f"p{k}", pattern, np.eye(2), half_vector(10.0 * k, 0.0, 0.0, 0.0), 1e-6)
    assert 0 < texture.pairs < MIN_PAIRS and texture.share == 0.0


def views(grids: list[np.ndarray]) -> StaticTexture:
    """One grain pattern seen alike by views with these footprints (half vectors 10° apart: no glint shared),
    each with a block variance of 1e-6 per unit of footprint area (the static error's σ² ∝ 1/area)."""
    texture, grain = StaticTexture(), np.random.default_rng(0).standard_normal((7, 7))
    for k, grid in enumerate(grids):
        texture.observe(f"v{k}", grain, grid, half_vector(5.0 * k, 0.0, 5.0 * k, 180.0),
                        1e-6 / abs(np.linalg.det(grid)))
    return texture


def test_one_footprint_for_every_view_makes_the_whole_grain_common():
    texture = views([np.eye(2)] * 30)
    assert texture.share == pytest.approx(1.0)
    assert all(texture.common_variance(f"v{k}", np.eye(2)) == pytest.approx(1e-6) for k in range(30))


def test_a_small_footprint_among_long_ones_shares_least_of_its_grain():
    """A view along the normal (footprint 1) among views at 60° (footprint 2, holding it): its static error
    (σ² = 1e-6) is the largest and the campaign's mean takes only part of it; theirs (5e-7) nearly all."""
    tilted = np.diag([2.0, 1.0])
    texture = views([tilted] * 30 + [np.eye(2)])
    normal, long = texture.common_variance("v30", np.eye(2)), texture.common_variance("v0", tilted)
    assert normal < 0.75e-6 and long == pytest.approx(5e-7, rel=0.1)


def test_views_with_nearby_half_vectors_share_their_glints():
    """Views of the same area whose half vectors lie within half a degree see the same glints: their patterns share
    the glints' part beyond the static grain (`glint_excess`, its first bin), and a view of a cluster that is half
    the run has that much more of its error in the campaign's mean (`common_variance`); a lone view has less than
    none."""
    rng = np.random.default_rng(3)
    shape = (30, 30)                                              # large patterns: chance products small
    grain = 0.5 * rng.standard_normal(shape)                      # static: a sixth of each pattern's power
    texture, sizes = StaticTexture(), (40, 10, 10, 10, 1)
    for c, size in enumerate(sizes):                              # clusters of half vectors 10° apart
        glints = rng.standard_normal(shape)                       # two thirds, shared within the cluster
        for k in range(size):
            pattern = grain + glints + 0.5 * rng.standard_normal(shape)
            texture.observe(f"c{c}-{k}", pattern, np.eye(2), half_vector(20.0 * c + 0.02 * k, 0.0, 0.0, 0.0),
                            1e-6)
    assert texture.share == pytest.approx(1 / 6, abs=0.05)
    assert texture.glint_excess()[0] == pytest.approx(2 / 3, abs=0.07)
    assert np.all(texture.glint_excess()[1:] == 0.0)             # no pairs that far apart: nothing assumed
    own = 6e-6                                                    # the view's whole texture variance (relative)
    # The first asked: 2 Cov(t, t̄) − Var(t̄) with Var(t̄) its own Cov(t, t̄) (the only view asked yet)
    member = texture.common_variance("c0-0", np.eye(2), half_vector(0.0, 0.0, 0.0, 0.0), own)
    glint = own * texture.glint_excess()[0] * 40 / 71             # its cluster's share of the run's views
    assert member == pytest.approx(texture.share * 1e-6 + glint, rel=0.01)
    assert glint > 2 * texture.share * 1e-6
    # A lone view shares the static grain but none of the glints that make most of the campaign's mean: it varies
    # about that mean by more than its own texture (its common variance is negative, and adds to its u)
    lone = texture.common_variance("c4-0", np.eye(2), half_vector(80.0, 0.0, 0.0, 0.0), own)
    itself = own * texture.glint_excess()[0] / 71                # its glints in the mean: its own 1/71 of it
    assert lone == pytest.approx(texture.share * 1e-6 + 2 * itself - (glint + itself) / 2, rel=0.01) and lone < 0
