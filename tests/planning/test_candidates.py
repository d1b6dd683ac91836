"""An adaptive campaign's candidate domain and first pass (rig.planning.candidates)."""

import numpy as np
import pytest

from repo_paths import TEST_CAMPAIGNS
from rig.config.campaign import CampaignError, load_campaign
from rig.config.rigfile import RigConfig
from rig.physics import geometry as geo
from rig.planning.candidates import candidate_plan, filled_thetas, first_pass, mandatory_ids, spread_views
from rig.planning.plan import build_plan

CAMPAIGN = load_campaign(TEST_CAMPAIGNS / "e2e-adaptive.yaml")


def test_an_incidence_range_is_filled_at_its_finest_step():
    assert filled_thetas([0, 10, 20, 30, 40, 50, 60, 70, 80, 85]) == pytest.approx(list(range(0, 86, 5)))
    assert filled_thetas([70, 80, 85]) == pytest.approx([70, 75, 80, 85])
    assert filled_thetas([3.3, 10.7]) == pytest.approx([3.3, 10.7])
    assert filled_thetas([40]) == [40]


def test_candidate_ids_do_not_depend_on_the_mandatory_pairs():
    rig = RigConfig()
    with_mandatory = {p.point_id: p for p in candidate_plan(CAMPAIGN, rig).points}
    bare = CAMPAIGN.model_copy(update={"sampling": CAMPAIGN.sampling.model_copy(update={"mandatory": []})})
    without = {p.point_id: p for p in candidate_plan(bare, rig).points}
    for pid, p in without.items():
        q = with_mandatory[pid]
        assert (q.theta_i_deg, q.phi_i_deg, q.theta_o_deg, q.phi_o_deg) == pytest.approx(
            (p.theta_i_deg, p.phi_i_deg, p.theta_o_deg, p.phi_o_deg))


def test_the_first_pass_holds_the_mandatory_pair_and_spreads_its_views():
    rig = RigConfig()
    candidates = candidate_plan(CAMPAIGN, rig)
    chosen = first_pass(CAMPAIGN, candidates)
    assert mandatory_ids(CAMPAIGN, candidates)[0] in {p.point_id for p in chosen}
    thetas = sorted({p.theta_i_deg for p in chosen})
    assert thetas == pytest.approx([0.0, 30.0, 85.0])            # two spread incidences + the mandatory one
    at_85 = [p for p in chosen if p.theta_i_deg == pytest.approx(85.0)]
    assert len(at_85) == CAMPAIGN.sampling.batch_points
    plan = build_plan(CAMPAIGN, rig)
    assert {p.point_id for p in plan.points} == {p.point_id for p in chosen} and plan.skipped == ()


def test_spread_views_start_at_the_lobes_and_fill_the_disk():
    candidates = candidate_plan(CAMPAIGN, RigConfig())
    here = [p for p in candidates.points if p.theta_i_deg == pytest.approx(40.0)]
    views = spread_views(here, 6)
    xy = geo.disk_coordinates(np.array([p.theta_o_deg for p in views]), np.array([p.phi_o_deg for p in views]),
                              0.0)
    s = np.sin(np.radians(40.0))
    assert np.min(np.hypot(xy[:, 0] + s, xy[:, 1])) < 0.1 and np.min(np.hypot(xy[:, 0] - s, xy[:, 1])) < 0.1
    # farthest-point sampling: no two chosen views nearly coincide
    d = np.hypot(*(xy[:, None] - xy[None]).transpose(2, 0, 1))
    assert np.min(d[np.triu_indices(len(views), 1)]) > 0.1


def test_a_mandatory_pair_the_rig_cannot_measure_is_refused_by_name():
    bad = CAMPAIGN.model_copy(update={"sampling": CAMPAIGN.sampling.model_copy(
        update={"mandatory": [(30.0, 0.0, 30.0, 0.0)]})})                  # looking into the lamp
    with pytest.raises(CampaignError, match=r"sampling.mandatory\[0\].*lamp housing"):
        build_plan(bad, RigConfig())
