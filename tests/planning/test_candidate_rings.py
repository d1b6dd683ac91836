"""Views between the patterns' rings as adaptive candidates, and which candidates are the patterns' own
(rig.planning.candidates.between_rings, pattern_ids; issue 33)."""

import numpy as np
import pytest

from repo_paths import TEST_CAMPAIGNS
from rig.config.campaign import IncidenceSeries, load_campaign
from rig.config.rigfile import RigConfig
from rig.physics import geometry as geo
from rig.planning.candidates import (
    candidate_plan,
    filled_thetas,
    first_pass,
    mandatory_ids,
    one_per_isotropic_pair,
    pattern_ids,
)
from rig.planning.table import table_plan

CAMPAIGN = load_campaign(TEST_CAMPAIGNS / "e2e-adaptive.yaml")


def angle_from(p, centre_deg):
    """Angle (degrees) of the view from the direction (θ, φ) `centre_deg`."""
    wo = geo.sph_to_vec(np.radians(p.theta_o_deg), np.radians(p.phi_o_deg))
    return float(np.degrees(geo.angle_between(wo, geo.sph_to_vec(*np.radians(centre_deg)))))


def test_views_half_way_between_the_rings_are_candidates_and_the_patterns_own_keep_their_ids():
    rig = RigConfig()
    candidates = candidate_plan(CAMPAIGN, rig)
    at_40 = [p for p in candidates.points if p.theta_i_deg == pytest.approx(40.0)]
    # the retroreflection pattern's rings 3.3, 10.7, 21.3, 34.8, 50.8 get 7.0, 16.0, 28.05, 42.8 between them
    rings = {round(angle_from(p, (40.0, 0.0)), 2) for p in at_40}
    assert {7.0, 16.0, 28.05, 42.8} <= rings
    # the table's own views (filled incidences, no rings, no mandatory pair) are candidates by the same ids
    bare = CAMPAIGN.model_copy(update={
        "incidence": [IncidenceSeries(phi=e.phi, theta=filled_thetas(e.theta)) for e in CAMPAIGN.incidence],
        "sampling": CAMPAIGN.sampling.model_copy(update={"mandatory": []})})
    by_id = {p.point_id: p for p in candidates.points}
    own = [p for p in one_per_isotropic_pair(table_plan(bare, rig).points) if p.point_id in by_id]  # one is the
    assert len(own) > 100                                           # mandatory pair's twin, dropped for it
    for p in own:
        q = by_id[p.point_id]
        assert (q.theta_i_deg, q.theta_o_deg, q.phi_o_deg) == pytest.approx((p.theta_i_deg, p.theta_o_deg, p.phi_o_deg))
    # ...and they are what pattern_ids names (the mandatory pair here is one of them: the mirror view at 30°)
    mandatory = set(mandatory_ids(CAMPAIGN, candidates))
    assert pattern_ids(CAMPAIGN, candidates) - mandatory == {p.point_id for p in own} - mandatory
    assert len(candidates.points) > 1.5 * len(own)


def test_the_first_pass_takes_the_patterns_own_views_not_the_rings_between():
    """A first-pass incidence's hull is the table's, at the table's cost: the rings between are left for batches."""
    candidates = candidate_plan(CAMPAIGN, RigConfig())
    own = pattern_ids(CAMPAIGN, candidates)
    chosen = first_pass(CAMPAIGN, candidates)
    assert {p.point_id for p in chosen} <= own | set(mandatory_ids(CAMPAIGN, candidates))
