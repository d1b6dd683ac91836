"""Motion physics of a simulated axis, on the simulated clock."""

import numpy as np
import pytest

from rig.config.rigfile import AxisConfig, RigConfig, SimulationConfig
from rig.core.motion import move_time_s, position_at
from rig.physics.brdf_models import get_model
from rig.simulators.axis_model import Alarm, AxisModel
from rig.simulators.world import SimWorld

CFG = AxisConfig(limits_deg=(-90, 90), speed_deg_s=10, accel_deg_s2=20, settle_s=0.2)


def make(sigma=0.0, backlash=0.0, zero_sigma=0.0, seed=1):
    sim = SimulationConfig(seed=seed, positioning_sigma_deg=sigma, axis_zero_sigma_deg=zero_sigma)
    world = SimWorld(RigConfig(simulation=sim), get_model("lambert"), {"kd": 0.5})
    return world, AxisModel(world, "stage_vertical", CFG, steps_per_degree=1000, backlash_deg=backlash)


def move(world, model, target):
    model.start_move(target, CFG.speed_deg_s, CFG.accel_deg_s2)
    world.clock.sleep(move_time_s(target - model.state().command_deg, 10, 20) + CFG.settle_s)


@pytest.mark.parametrize("distance", [40.0, 1.0])          # trapezoid and triangle
def test_in_position_exactly_after_profile_plus_settle(distance):
    world, model = make()
    model.start_move(distance, 10, 20)
    total = move_time_s(distance, 10, 20) + CFG.settle_s
    world.clock.sleep(total - 1e-6)
    assert model.state().busy and not model.state().in_position
    world.clock.sleep(2e-6)
    state = model.state()
    assert state.in_position and not state.busy and state.command_deg == pytest.approx(distance, abs=1e-12)


def test_positions_during_the_move_follow_the_trapezoid():
    world, model = make()
    model.start_move(40.0, 10, 20)
    elapsed = 0.0
    for t in (0.25, 1.0, 2.5, 4.4):
        world.clock.sleep(t - elapsed)
        elapsed = t
        assert model.command_position_deg() == pytest.approx(position_at(0.0, 40.0, t, 10, 20), abs=1e-12)
        assert model.true_position_deg() == pytest.approx(model.command_position_deg(), abs=1e-12)
    assert 0 < model.true_position_deg() < 40


def test_encoder_is_quantised_to_steps():
    world, model = make()
    move(world, model, 12.3456)
    state = model.state()
    assert state.true_deg == pytest.approx(12.3456)
    assert state.encoder_steps == 12346 and state.command_steps == 12346


def test_backlash_appears_on_direction_reversal():
    world, model = make(backlash=0.002)
    move(world, model, 10.0)
    from_below = model.true_position_deg()
    move(world, model, 15.0)
    assert model.true_position_deg() == pytest.approx(15.0 - 0.001)     # same direction: same side
    move(world, model, 10.0)
    from_above = model.true_position_deg()
    assert from_above - from_below == pytest.approx(0.002)
    assert (from_below, from_above) == (pytest.approx(9.999), pytest.approx(10.001))
    assert model.state().command_deg == pytest.approx(10.0, abs=1e-12)    # the controller does not know


def test_repeatability_spread_matches_positioning_sigma():
    world, model = make(sigma=0.003)
    landings = []
    for _ in range(300):
        move(world, model, 20.0)
        move(world, model, 10.0)
        landings.append(model.true_position_deg())
    assert np.std(landings) == pytest.approx(0.003, rel=0.15)
    assert np.mean(landings) == pytest.approx(10.0, abs=0.0006)


def test_zero_errors_spread_with_axis_zero_sigma_across_runs():
    offsets = np.array([make(zero_sigma=0.01, seed=seed)[1].zero_offset_deg for seed in range(400)])
    assert offsets.std() == pytest.approx(0.01, rel=0.15)
    assert abs(offsets.mean()) < 3 * 0.01 / np.sqrt(400)
    world, first = make(zero_sigma=0.01)
    others = [AxisModel(world, name, CFG, steps_per_degree=1000) for name in ("stage_normal", "arm_polar")]
    draws = sorted([first.zero_offset_deg, *(m.zero_offset_deg for m in others)])
    assert np.diff(draws).min() > 1e-9                                     # one draw per axis, none shared


def test_zero_error_is_fixed_for_the_run_and_invisible_in_the_read_back():
    world, model = make(sigma=0.003, backlash=0.002, zero_sigma=1.0)
    offset = model.zero_offset_deg
    assert abs(offset) > 0.1                                               # this seed's draw: plainly visible

    def check(target):
        state = model.state()
        reading = state.encoder_steps / 1000
        assert abs(reading - target) < 0.001 + 0.0006 + 5 * 0.003         # steps, backlash, repeatability
        assert reading == pytest.approx(model.encoder_position_deg(), abs=0.0005)
        assert world.axis_truth["stage_vertical"]() == pytest.approx(model.encoder_position_deg() + offset, abs=1e-12)
        assert state.true_deg == pytest.approx(model.encoder_position_deg() + offset, abs=1e-12)

    for target in (10.0, -20.0, 35.5, 35.5):
        move(world, model, target)
        check(target)
    model.home()                                                           # the home sensor is off by the offset
    world.clock.sleep(10.0)
    assert model.state().homed
    check(0.0)


def test_target_beyond_soft_limits_raises_overtravel_alarm_and_moves_nothing():
    world, model = make()
    move(world, model, 5.0)
    model.start_move(95.0, 10, 20)
    state = model.state()
    assert state.alarm == Alarm.OVERTRAVEL and not state.busy and not state.in_position
    model.start_move(10.0, 10, 20)                                         # ignored while the alarm is present
    world.clock.sleep(5.0)
    assert model.true_position_deg() == pytest.approx(5.0, abs=1e-12) and model.state().alarm == Alarm.OVERTRAVEL
    model.reset_alarm()
    move(world, model, 10.0)
    assert model.state().in_position and model.true_position_deg() == pytest.approx(10.0, abs=1e-12)


def test_overtravel_during_a_move_halts_where_the_axis_is():
    world, model = make()
    model.start_move(40.0, 10, 20)
    world.clock.sleep(1.0)
    model.start_move(-95.0, 10, 20)
    world.clock.sleep(5.0)
    assert model.true_position_deg() == pytest.approx(position_at(0.0, 40.0, 1.0, 10, 20))


def test_homing_takes_the_run_plus_the_sensor_search_and_sets_homed():
    world, model = make(backlash=0.002)
    move(world, model, 20.0)
    assert not model.state().homed
    model.home()
    duration = move_time_s(20.0, 10, 20) + model.home_search_s + CFG.settle_s
    world.clock.sleep(duration - 1e-6)
    assert model.state().busy and not model.state().homed
    world.clock.sleep(2e-6)
    state = model.state()
    assert state.homed and state.in_position and state.command_deg == pytest.approx(0.0, abs=1e-12)
    assert state.true_deg == pytest.approx(-0.001)                         # final approach in +
    move(world, model, 5.0)
    assert model.state().homed                                             # kept after later moves


def test_stop_halts_at_once_and_settles():
    world, model = make()
    model.start_move(40.0, 10, 20)
    world.clock.sleep(1.0)
    model.stop()
    here = position_at(0.0, 40.0, 1.0, 10, 20)
    assert model.state().busy
    world.clock.sleep(CFG.settle_s + 1e-9)
    assert model.state().in_position and model.true_position_deg() == pytest.approx(here)


def test_injected_alarm_ends_the_next_move_until_reset():
    world, model = make()
    model.inject_alarm()
    model.start_move(10.0, 10, 20)
    world.clock.sleep(0.5)
    assert model.state().busy and model.state().alarm == 0
    world.clock.sleep(move_time_s(10.0, 10, 20))
    assert model.state().alarm == Alarm.DEVIATION and not model.state().in_position
    model.reset_alarm()
    move(world, model, 0.0)
    assert model.state().in_position and model.state().alarm == 0


def test_true_position_is_registered_for_the_camera():
    world, model = make()
    move(world, model, 7.5)
    assert world.axis_truth["stage_vertical"]() == pytest.approx(7.5, abs=1e-12)
    assert world.motor_angles_deg()[0] == pytest.approx(7.5, abs=1e-12)
