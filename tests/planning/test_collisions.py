"""Forbidden zones: positions inside and moves across are refused with the zone's name; moves beside are kept."""

import numpy as np
import pytest
from pydantic import ValidationError

from rig.config.campaign import parse_campaign
from rig.config.rigfile import AxesConfig, AxisConfig, RigConfig
from rig.config.zones import CollisionsConfig, ForbiddenZone
from rig.planning.collisions import SAMPLE_STEP_DEG, move_positions, path_crosses, zone_at
from rig.planning.plan import build_plan
from rig.planning.points import SKIP_REASONS, describe_reason

HOME = (0.0, 0.0, 0.0, 0.0)
AXES = RigConfig().axes
#: Motor angles come from inverse kinematics (trigonometry): compared to the contract's 1e-9°, never exactly.
TOL_DEG = 1e-9
# at θi = 0 (stage at home) the view θo = 20° lies at (a, b) = (-90°, 70°) for φo = 90° and (-70°, 90°) for φo = 0°
VIEW_A, VIEW_B = [20, 90], [20, 0]
MOTORS_A, MOTORS_B = (0.0, 0.0, -90.0, 70.0), (0.0, 0.0, -70.0, 90.0)


def assert_motors(plan, expected):
    """The plan's points have these motor angles (degrees, within TOL_DEG), in this order."""
    got = [p.motors_deg for p in plan.points]
    assert len(got) == len(expected), got
    np.testing.assert_allclose(np.reshape(got, (-1, 4)), np.reshape(expected, (-1, 4)), rtol=0, atol=TOL_DEG)


def zone(name, azimuth, polar):
    return ForbiddenZone(name=name, arm_azimuth=azimuth, arm_polar=polar)


def plan_with(zones, views, ordering="table"):
    c = parse_campaign({"name": "t", "sample": {"id": "s"}, "incidence": [{"phi": 0, "theta": [0]}],
                        "viewing": [{"points": views}]})
    return build_plan(c, RigConfig(collisions=CollisionsConfig(zones=zones)), ordering=ordering)


def test_zone_validation():
    with pytest.raises(ValidationError, match="restricts no axis"):
        ForbiddenZone(name="z")
    with pytest.raises(ValidationError, match="low < high"):
        zone("z", (10, -10), None)
    with pytest.raises(ValidationError):
        ForbiddenZone(name="a:b", arm_polar=(0, 1))             # ':' separates reason and zone
    with pytest.raises(ValidationError, match="unique"):
        CollisionsConfig(zones=[zone("z", (0, 1), None), zone("z", (2, 3), None)])
    parsed = CollisionsConfig.model_validate({"zones": [{"name": "lamp_lever", "arm_azimuth": [-100, -80],
                                                         "arm_polar": [80, 100]}]})
    assert parsed.zones[0].arm_polar == (80, 100) and parsed.zones[0].stage_vertical is None


def test_zone_at_first_zone_wins_and_nan_is_nowhere():
    zones = [zone("a", (-10, 10), None), zone("b", (0, 20), (-5, 5))]
    pos = np.array([[0, 0, 5, 0], [0, 0, 15, 0], [0, 0, 15, 50], [np.nan] * 4])
    assert list(zone_at(pos, zones)) == ["a", "b", "", ""]


def test_move_across_is_refused_beside_is_kept():
    assert path_crosses(HOME, MOTORS_A, [zone("mid", (-50, -40), (35, 55))], AXES) == "mid"
    assert path_crosses(HOME, MOTORS_A, [zone("beside", (-50, -40), (0, 20))], AXES) is None
    assert path_crosses(HOME, MOTORS_A, [zone("target", (-95, -85), (65, 75))], AXES) == "target"


def test_path_follows_the_profiles_not_the_chord():
    """A fast polar axis finishes first: the path bends away from the straight line in motor space."""
    fast = AxesConfig(arm_azimuth=AxisConfig(limits_deg=(-180, 180), speed_deg_s=10, accel_deg_s2=20),
                      arm_polar=AxisConfig(limits_deg=(-180, 180), speed_deg_s=60, accel_deg_s2=240))
    target = (0.0, 0.0, -90.0, 90.0)
    assert path_crosses(HOME, target, [zone("bend", (-40, -30), (80, 95))], fast) == "bend"
    assert path_crosses(HOME, target, [zone("chord", (-70, -60), (55, 70))], fast) is None
    steps = np.abs(np.diff(move_positions(fast, HOME, target), axis=0))
    assert steps.max() <= SAMPLE_STEP_DEG * (1 + 1e-9)


def test_point_inside_a_zone_uses_the_other_branch_or_is_refused():
    lever = zone("lever", (-100, -80), (60, 80))
    plan = plan_with([lever], [VIEW_A])
    assert not plan.skipped
    assert_motors(plan, [(0.0, 0.0, 90.0, -70.0)])
    plan = plan_with([lever, zone("twin", (80, 100), (-80, -60))], [VIEW_A])
    assert not plan.points and [s.reason for s in plan.skipped] == ["forbidden_zone:lever"]


def test_move_across_a_zone_takes_the_other_branch_if_that_is_clear():
    plan = plan_with([zone("high", (-95, -83), (72, 85))], [VIEW_A, VIEW_B])
    assert not plan.skipped                                      # A → B crosses, A → B's twin does not
    assert_motors(plan, [MOTORS_A, (0.0, 0.0, 110.0, -90.0)])


def test_move_across_a_zone_on_every_branch_is_refused_and_the_next_starts_from_the_last_kept():
    corner, twin = zone("corner", (-85, -75), (65, 72)), zone("twin", (75, 85), (-72, -65))
    plan = plan_with([corner, twin], [VIEW_A, VIEW_B])
    assert [(s.point_id, s.reason) for s in plan.skipped] == [("00-000", "collision:corner")]
    assert_motors(plan, [MOTORS_B])                              # home → B passes beside both
    # from A the move to B would cross `high` and go to B's twin: from home it does not
    plan = plan_with([corner, twin, zone("high", (-95, -83), (72, 85))], [VIEW_A, VIEW_B])
    assert_motors(plan, [MOTORS_B])


def test_optimised_order_checks_its_own_moves():
    zones = [zone("mid", (-50, -40), (35, 55))]
    plan = plan_with(zones, [VIEW_A, VIEW_B, [40, 90], [30, 45]], ordering="optimised")
    assert plan.n_planned == 4 and {s.reason for s in plan.skipped} <= {"collision:mid"}
    here = HOME
    for p in plan.points:
        assert path_crosses(here, p.motors_deg, zones, AXES) is None
        here = p.motors_deg


def test_describe_reason():
    assert describe_reason("roi_unlit") == SKIP_REASONS["roi_unlit"]
    assert describe_reason("collision:lamp_lever").endswith(": lamp_lever")
    assert describe_reason("forbidden_zone:lamp_lever").startswith(SKIP_REASONS["forbidden_zone"])


def test_rig_without_collisions_section_has_no_zones():
    c = parse_campaign({"name": "t", "sample": {"id": "s"}, "incidence": [{"phi": 0, "theta": [0]}],
                        "viewing": [{"points": [VIEW_A]}]})
    assert_motors(build_plan(c, RigConfig(), ordering="table"), [MOTORS_A])
