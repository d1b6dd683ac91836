"""An adaptive campaign's candidate domain and first pass (rig.planning.candidates)."""

import numpy as np
import pytest

from repo_paths import TEST_CAMPAIGNS
from rig.config.campaign import CampaignError, load_campaign
from rig.config.rigfile import RigConfig
from rig.physics import geometry as geo
from rig.planning.candidates import (
    candidate_plan,
    filled_thetas,
    first_pass,
    isotropic_key,
    mandatory_ids,
    one_per_isotropic_pair,
    spread_views,
)
from rig.planning.plan import build_plan
from rig.planning.table import table_plan

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


def test_a_view_and_its_mirror_image_are_one_candidate():
    """The viewing patterns are symmetric about the plane of incidence; an isotropic BRDF (which the interpolant
    assumes) has one value for a view and its mirror image, so only the first is a candidate."""
    rig = RigConfig()
    table = table_plan(CAMPAIGN.model_copy(update={"sampling": CAMPAIGN.sampling.model_copy(
        update={"mandatory": []})}), rig).points
    at_40 = [p for p in table if p.theta_i_deg == pytest.approx(40.0)]
    kept = one_per_isotropic_pair(at_40)
    mirrored = {(round(p.theta_o_deg, 6), round(float(geo.wrap_360(-p.phi_o_deg)), 6)) for p in kept}
    assert 0.45 * len(at_40) < len(kept) < 0.7 * len(at_40)        # pairs (0 and 180° are their own images)
    assert len({isotropic_key(p) for p in kept}) == len(kept) == len({isotropic_key(p) for p in at_40})
    assert any((round(p.theta_o_deg, 6), round(p.phi_o_deg, 6)) in mirrored for p in at_40 if p not in kept)
    assert [p.point_id for p in kept] == sorted((p.point_id for p in kept), key=[q.point_id for q in at_40].index)


def test_a_mandatory_pair_is_kept_and_its_mirror_image_dropped():
    rig = RigConfig()
    bare = CAMPAIGN.model_copy(update={"sampling": CAMPAIGN.sampling.model_copy(update={"mandatory": []})})
    at_40 = [p for p in candidate_plan(bare, rig).points if p.theta_i_deg == pytest.approx(40.0)]
    first = next(p for p in at_40 if 10 < geo.wrap_360(p.phi_o_deg) < 170 and p.theta_o_deg > 5)
    mirror = (40.0, 0.0, first.theta_o_deg, float(geo.wrap_360(-first.phi_o_deg)))       # later in the table
    twin = CAMPAIGN.model_copy(update={"sampling": CAMPAIGN.sampling.model_copy(update={"mandatory": [mirror]})})
    candidates = candidate_plan(twin, rig)
    (pid,) = mandatory_ids(twin, candidates)
    assert pid != first.point_id
    assert [p.point_id for p in candidates.points if isotropic_key(p) == isotropic_key(first)] == [pid]
