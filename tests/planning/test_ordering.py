"""Travel-time ordering: a permutation of the table plan, series contiguous, deterministic, and faster."""

import itertools

import numpy as np
import pytest

from repo_paths import ROOT
from rig.config.campaign import load_campaign, parse_campaign
from rig.config.rigfile import AxesConfig, AxisConfig, RigConfig, camera_optics
from rig.core.motion import move_time_s
from rig.physics import geometry as geo
from rig.physics.optics import roi_inside_spot
from rig.planning.collisions import zones_of
from rig.planning.ordering import (
    START_DEG,
    arm_branches,
    choose_branches,
    nearest_neighbour,
    open_path,
    order_plan,
    travel_time_s,
    two_opt,
)
from rig.planning.plan import build_plan, estimate_rig_time_s, rig_time_comparison

RIG = RigConfig()


@pytest.fixture(scope="module")
def paper():
    c = load_campaign(ROOT / "campaigns" / "spieringhs2023-rm1.yaml")
    return c, build_plan(c, RIG, ordering="table"), build_plan(c, RIG, ordering="optimised")


def path_cost(from_start, cost, order):
    return from_start[order[0]] + cost[order[:-1], order[1:]].sum()


def random_instance(seed, n=40):
    """Random arm positions of one series (stage fixed) and their travel-time matrix."""
    rng = np.random.default_rng(seed)
    pos = np.c_[np.full((n, 2), [-30.0, 0.0]), rng.uniform(-180, 180, n), rng.uniform(-150, 150, n)]
    return travel_time_s(RIG.axes, START_DEG, pos), travel_time_s(RIG.axes, pos[:, None], pos[None, :])


def test_vectorised_trapezoid_matches_motion():
    rng = np.random.default_rng(1)
    d, v, a = rng.uniform(-200, 200, 500), rng.uniform(1, 30, 500), rng.uniform(1, 60, 500)
    want = [move_time_s(*x) for x in zip(d, v, a)]
    np.testing.assert_allclose(move_time_s(d, v, a), want, rtol=1e-14)


def test_ordering_is_a_permutation_with_ids_unchanged(paper):
    _, table, opt = paper
    assert sorted(p.point_id for p in opt.points) == sorted(p.point_id for p in table.points)
    assert opt.skipped == table.skipped
    assert sorted(opt.series, key=lambda s: s.index) == list(table.series)
    same = {p.point_id: p for p in table.points}
    for p in opt.points:
        q = same[p.point_id]
        assert (p.series, p.theta_i_deg, p.phi_i_deg, p.theta_o_deg, p.phi_o_deg) == \
               (q.series, q.theta_i_deg, q.phi_i_deg, q.theta_o_deg, q.phi_o_deg)
        assert p.motors_deg[:2] == q.motors_deg[:2]          # the stage of a series does not change


def test_each_series_contiguous_in_series_order(paper):
    _, _, opt = paper
    runs = [k for k, _ in itertools.groupby(p.series for p in opt.points)]
    assert runs == [s.index for s in opt.series]


def test_deterministic(paper):
    c, _, opt = paper
    assert build_plan(c, RIG) == opt                           # optimised is the default


def test_optimised_needs_at_most_six_tenths_of_table_time(paper):
    c, table, opt = paper
    table_s, opt_s = rig_time_comparison(c, RIG, capture_s_per_point=0.05)     # rig plan's nominal capture
    assert (table_s, opt_s) == pytest.approx((estimate_rig_time_s(table, RIG.axes, 0.05),
                                              estimate_rig_time_s(opt, RIG.axes, 0.05)), rel=1e-12)
    assert opt_s <= 0.6 * table_s
    assert estimate_rig_time_s(opt, RIG.axes, 0.0) <= 0.6 * estimate_rig_time_s(table, RIG.axes, 0.0)    # moves alone


def test_switched_branches_reproduce_the_requested_angles(paper):
    _, table, opt = paper
    before = {p.point_id: p.motors_deg for p in table.points}
    switched = [p for p in opt.points if p.motors_deg != before[p.point_id]]
    assert len(switched) > 100
    m = np.array([p.motors_deg for p in opt.points])
    want = np.array([[p.theta_i_deg, p.phi_i_deg, p.theta_o_deg, p.phi_o_deg] for p in opt.points])
    fk = geo.forward_deg(*m.T, phi_i_at_pole_deg=want[:, 1], phi_o_at_pole_deg=want[:, 3])
    got = np.c_[fk.theta_i_deg, fk.phi_i_deg, fk.theta_o_deg, fk.phi_o_deg]
    err = np.abs(got - want)
    err[:, [1, 3]] = np.abs(geo.wrap_360(got[:, [1, 3]] - want[:, [1, 3]] + 180) - 180)
    assert err.max() < 1e-9
    lim = RIG.axes.limits()
    for k, name in enumerate(geo.AXIS_NAMES):
        lo, hi = getattr(lim, name)
        assert np.all((m[:, k] >= lo) & (m[:, k] <= hi))


def test_switched_branch_keeps_the_roi_lit(paper):
    """The other branch turns the image by 180° about the optical axis: the central ROI stays lit."""
    c, _, opt = paper
    m = np.radians(np.array([p.motors_deg for p in opt.points]))
    assert np.all(roi_inside_spot(*m.T, c.capture.roi_px, camera_optics(RIG),
                                  RIG.geometry.spot_diameter_m / 2))


@pytest.mark.parametrize("seed", range(5))
def test_two_opt_not_worse_than_nn_not_worse_than_table(seed):
    from_start, cost = random_instance(seed)
    nn = nearest_neighbour(from_start, cost)
    opt = two_opt(from_start, cost, nn)
    assert sorted(opt) == list(range(len(cost)))
    table = path_cost(from_start, cost, np.arange(len(cost)))
    assert path_cost(from_start, cost, opt) <= path_cost(from_start, cost, nn) <= table


def test_two_opt_leaves_no_improving_reversal():
    from_start, cost = random_instance(7, n=12)
    order = open_path(from_start, cost)
    best = path_cost(from_start, cost, order)
    for i, j in itertools.combinations(range(len(order) + 1), 2):
        trial = np.r_[order[:i], order[i:j][::-1], order[j:]]
        assert path_cost(from_start, cost, trial) >= best - 1e-9


def test_choose_branches_is_the_best_sequence():
    rng = np.random.default_rng(3)
    motors = np.c_[np.zeros((6, 2)), rng.uniform(-180, 180, 6), rng.uniform(-180, 180, 6)]
    cand = arm_branches(motors, RIG.axes.limits())
    chosen = choose_branches(RIG.axes, np.zeros(4), cand)

    def total(pick):
        pos = cand[np.arange(len(cand)), list(pick)]
        return np.sum(travel_time_s(RIG.axes, np.vstack([np.zeros(4), pos[:-1]]), pos))

    brute = min((p for p in itertools.product(range(3), repeat=len(cand))
                 if np.all(np.isfinite(cand[np.arange(len(cand)), list(p)]))), key=total)
    assert total(chosen) == pytest.approx(total(brute), abs=1e-12)


def test_arm_branches_same_direction_and_inside_limits():
    limits = geo.AxisLimits(arm_polar=(-100, 150))
    motors = np.array([[-20.0, 30.0, 50.0, 120.0], [-20.0, 30.0, -170.0, 60.0]])
    cand = arm_branches(motors, limits)
    assert np.isnan(cand[0, 1:]).all()                          # -120 is below the polar limit
    assert np.isnan(cand[1, 1]).all() and np.allclose(cand[1, 2], [-20, 30, 10, -60])
    cam = geo.camera_unit(*np.radians(cand[1, [0, 2], 2:]).T)
    np.testing.assert_allclose(cam[0], cam[1], atol=1e-15)


def test_order_plan_without_branch_switching_keeps_motors(paper):
    _, table, _ = paper
    fixed = order_plan(table, RIG.axes, zones_of(RIG), START_DEG, switch_branches=False)
    before = {p.point_id: p.motors_deg for p in table.points}
    assert all(p.motors_deg == before[p.point_id] for p in fixed.points)


def test_narrow_limits_still_skip_and_never_leave_limits():
    narrow = AxesConfig(arm_polar=AxisConfig(limits_deg=(-30, 90), speed_deg_s=15, accel_deg_s2=30))
    c = parse_campaign({"name": "t", "sample": {"id": "s"}, "incidence": [{"phi": 0, "theta": [0, 40]}],
                        "viewing": [{"centred_on": "normal", "theta": [10, 40, 70], "phi": [0, 90, 180, 270]}]})
    plan = build_plan(c, RigConfig(axes=narrow))
    assert plan.skipped_by_reason().get("axis_limits", 0) > 0
    polar = np.array([p.motors_deg[3] for p in plan.points])
    assert np.all((polar >= -30) & (polar <= 90))


def test_empty_series_go_last():
    # the view is the retroreflection at θi = 60° (occluded) and measurable at θi = 0
    c = parse_campaign({"name": "t", "sample": {"id": "s"}, "incidence": [{"phi": 0, "theta": [60, 0]}],
                        "viewing": [{"points": [[60, 0]]}]})
    table, opt = build_plan(c, RIG, ordering="table"), build_plan(c, RIG)
    assert [s.index for s in table.series] == [0, 1] and [s.index for s in opt.series] == [1, 0]
    assert [p.point_id for p in opt.points] == ["01-000"]


def test_unknown_ordering_refused(paper):
    with pytest.raises(ValueError, match="ordering"):
        build_plan(paper[0], RIG, ordering="fastest")
