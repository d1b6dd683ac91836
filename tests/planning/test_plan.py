"""Planner: Table 1 × Table 2, stable ids, and every left-out point with its reason."""


import numpy as np
import pytest

from repo_paths import ROOT
from rig.config.campaign import load_campaign, parse_campaign
from rig.config.rigfile import AxesConfig, AxisConfig, RigConfig
from rig.physics import geometry as geo
from rig.physics.geometry import AxisLimits
from rig.planning.ordering import travel_time_s
from rig.planning.plan import build_plan, estimate_rig_time_s
from rig.planning.points import SKIP_REASONS
from rig.planning.table import viewing_directions

TABLE2_THETA = [3.3, 10.7, 21.3, 34.8, 50.8, 69.3]
TABLE2_PHI = [25.7, 51.4, 77.1, 102.9, 128.6, 154.3, 180, 205.7, 231.4, 257.1, 282.9, 308.6, 334.3, 360]


def campaign(incidence, viewing, **extra):
    return parse_campaign({"name": "t", "sample": {"id": "s"}, "incidence": incidence, "viewing": viewing,
                           **extra})


@pytest.fixture(scope="module")
def paper():
    c = load_campaign(ROOT / "campaigns" / "spieringhs2023-rm1.yaml")
    return c, build_plan(c, RigConfig())


def test_paper_campaign_counts(paper):
    c, plan = paper
    assert len(plan.series) == 16
    assert len(plan.points) > 1000
    # at normal incidence both centrings give Table 2 itself: 84 views, all measurable
    s0 = [p for p in plan.points if p.series == 0]
    assert len(s0) == 84 and not [s for s in plan.skipped if s.series == 0]
    got = sorted((round(p.theta_o_deg, 6), round(p.phi_o_deg, 6) % 360) for p in s0)
    want = sorted((t, round(f % 360, 6)) for t in TABLE2_THETA for f in TABLE2_PHI)
    np.testing.assert_allclose(got, want, atol=1e-9)
    assert set(plan.skipped_by_reason()) <= set(SKIP_REASONS)


def test_ids_stable_and_unique(paper):
    c, plan = paper
    again = build_plan(c, RigConfig())
    assert [p.point_id for p in again.points] == [p.point_id for p in plan.points]
    ids = [p.point_id for p in plan.points] + [s.point_id for s in plan.skipped]
    assert len(ids) == len(set(ids)) == plan.n_planned


def test_planned_motors_reproduce_requested_angles(paper):
    _, plan = paper
    m = np.array([p.motors_deg for p in plan.points])
    fk = geo.forward_deg(*m.T)
    want = np.array([[p.theta_i_deg, p.theta_o_deg] for p in plan.points])
    np.testing.assert_allclose(np.c_[fk.theta_i_deg, fk.theta_o_deg], want, atol=1e-9)


def test_centred_on_incidence_surrounds_incidence():
    c = campaign([{"phi": 30, "theta": [40]}], [{"centred_on": "incidence", "theta": [10], "phi": [0, 90, 180, 270]}])
    dirs = viewing_directions(c, 40, 30)
    wi = geo.sph_to_vec(np.radians(40), np.radians(30))
    np.testing.assert_allclose(np.degrees(geo.angle_between(dirs, wi)), 10, atol=1e-9)
    mirror = viewing_directions(campaign([{"phi": 30, "theta": [40]}],
                                         [{"centred_on": "mirror", "theta": [0], "phi": [0]}]), 40, 30)
    theta, phi = geo.vec_to_sph(mirror)
    assert np.degrees(theta[0]) == pytest.approx(40) and np.degrees(phi[0]) == pytest.approx(210)


def test_duplicate_views_removed():
    c = campaign([{"phi": 0, "theta": [0]}],
                 [{"centred_on": "normal", "theta": [20], "phi": [0, 360, 90]},
                  {"points": [[20, 90], [30, 45]]}])
    assert len(viewing_directions(c, 0, 0)) == 3


@pytest.mark.parametrize("views, reason", [
    ([[2.0, 0.0]], "occluded_by_lamp"),          # 2° from retroreflection at θi = 60°, inside 2.49°
    ([[88.0, 180.0]], "beyond_max_view_theta"),
    ([[60.0, 30.0]], "ok"),
])
def test_skip_reasons(views, reason):
    c = campaign([{"phi": 0, "theta": [60]}], [{"points": [[60 + views[0][0], 0]] if reason == "occluded_by_lamp"
                                                 else views}])
    plan = build_plan(c, RigConfig())
    if reason == "ok":
        assert len(plan.points) == 1 and not plan.skipped
    else:
        assert [s.reason for s in plan.skipped] == [reason]


def test_below_horizon_from_pattern():
    c = campaign([{"phi": 0, "theta": [85]}], [{"centred_on": "incidence", "theta": [10], "phi": [0]}])
    plan = build_plan(c, RigConfig())
    assert plan.skipped_by_reason() == {"below_horizon": 1}


def test_roi_unlit_at_grazing_view():
    c = campaign([{"phi": 0, "theta": [0]}], [{"points": [[60, 0], [84, 0]]}])
    plan = build_plan(c, RigConfig())
    assert [s.reason for s in plan.skipped] == ["roi_unlit"]
    keep = build_plan(campaign([{"phi": 0, "theta": [0]}], [{"points": [[84, 0]]}],
                               limits={"skip_roi_unlit": False}), RigConfig())
    assert len(keep.points) == 1


def test_axis_limits_reason():
    narrow = AxesConfig(arm_polar=AxisConfig(limits_deg=(-30, 30), speed_deg_s=15, accel_deg_s2=30))
    # at θi = 0 the normal is horizontal: θo = 70°, φo = 90° puts the camera 20° from the zenith
    c = campaign([{"phi": 0, "theta": [0]}], [{"points": [[10, 90], [70, 90]]}])
    plan = build_plan(c, RigConfig(axes=narrow))
    assert plan.skipped_by_reason() == {"axis_limits": 1}
    assert narrow.limits() == AxisLimits(arm_polar=(-30, 30))


def test_rig_time_estimate_matches_trapezoid():
    rig = RigConfig()
    cfg = rig.axes.arm_azimuth
    t = float(travel_time_s(rig.axes, (0, 0, 0, 0), (0, 0, 90, 0)))
    assert t == pytest.approx(90 / cfg.speed_deg_s + cfg.speed_deg_s / cfg.accel_deg_s2 + cfg.settle_s)
    assert float(travel_time_s(rig.axes, (0, 0, 0, 0), (0, 0, 0, 0))) == 0
    c = campaign([{"phi": 0, "theta": [0]}], [{"points": [[10, 0], [20, 0]]}])
    plan = build_plan(c, rig)
    assert estimate_rig_time_s(plan, rig.axes, 1.0) > 2.0
