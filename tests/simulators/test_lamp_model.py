"""The halogen-lamp model (rig.simulators.lamp): filament resistance, thermal lag, light output, burn-out."""

import math

import numpy as np
import pytest

from rig.config.rigfile import SimulationConfig
from rig.simulators.clock import SimClock
from rig.simulators.lamp import LampPhysics

NOMINAL_A = 4.17
SIM = SimulationConfig()


def lamp(clock: SimClock, *, warmup_amplitude: float = 0.0, drift_per_hour: float = 0.0) -> LampPhysics:
    return LampPhysics(clock, NOMINAL_A, SIM.lamp_exponent, warmup_amplitude, SIM.warmup_tau_s, drift_per_hour)


@pytest.fixture
def clock() -> SimClock:
    return SimClock()


def warm(lp: LampPhysics, current_a: float) -> None:
    lp.switch(True)
    lp.set_current(current_a)
    lp.clock.sleep(50 * lp.thermal_tau_s)


def test_cold_filament_is_a_tenth_of_hot(clock):
    lp = lamp(clock)
    assert lp.resistance_ohm() == pytest.approx(lp.hot_resistance_ohm / 10)
    warm(lp, NOMINAL_A)
    assert lp.resistance_ohm() == pytest.approx(12.0 / NOMINAL_A)            # rated 12 V at nominal current
    assert lp.voltage_v() == pytest.approx(12.0)
    lp.switch(False)
    clock.sleep(50 * lp.thermal_tau_s)
    assert lp.resistance_ohm() == pytest.approx(lp.cold_resistance_ohm)
    assert lp.voltage_v() == 0.0


def test_switching_on_cold_at_full_current_is_an_inrush(clock):
    lp = lamp(clock)
    lp.switch(True)
    lp.set_current(NOMINAL_A)
    assert lp.voltage_v() == pytest.approx(1.2)          # 4.17 A into the cold 0.29 Ω
    assert lp.voltage_v(clock.now() + 3.0) == pytest.approx(12.0)


def test_current_step_gives_a_first_order_voltage_transient(clock):
    lp = lamp(clock)
    warm(lp, 3.0)
    r_before = lp.resistance_ohm()
    lp.set_current(NOMINAL_A)
    t0, tau = clock.now(), lp.thermal_tau_s
    v0, v_end = NOMINAL_A * r_before, NOMINAL_A * lp.steady_resistance_ohm(NOMINAL_A)
    assert lp.voltage_v() == pytest.approx(v0)            # the filament has not heated yet
    times = t0 + tau * np.array([0.5, 1.0, 2.0, 5.0])
    volts = np.array([lp.voltage_v(t) for t in times])
    assert np.all(np.diff(volts) > 0) and volts[-1] < v_end
    expected = v_end - (v_end - v0) * np.exp(-(times - t0) / tau)
    np.testing.assert_allclose(volts, expected, rtol=1e-9)


def test_linear_ramp_heats_the_filament_without_overshoot(clock):
    lp = lamp(clock)
    lp.switch(True)
    lp.set_current(NOMINAL_A, ramp_s=5.0)
    volts = [lp.voltage_v(t) for t in np.linspace(0.0, 8.0, 81)]
    assert np.all(np.diff(volts) >= 0)
    assert max(volts) == pytest.approx(12.0)
    assert lp.current_a(2.5) == pytest.approx(NOMINAL_A / 2)        # the programmed ramp is linear


def test_light_output_goes_as_current_to_the_configured_exponent(clock):
    lp = lamp(clock)
    warm(lp, NOMINAL_A)
    assert lp.relative_output() == pytest.approx(1.0)
    currents = np.array([1.0, 2.0, 3.0, 4.17, 5.0])
    outputs = []
    for i in currents:
        lp.set_current(i)
        outputs.append(lp.relative_output())
    slope = np.polyfit(np.log(currents), np.log(outputs), 1)[0]
    assert slope == pytest.approx(SIM.lamp_exponent)
    assert SIM.lamp_exponent == pytest.approx(3.4)


def test_warm_up_and_ageing_drift(clock):
    lp = lamp(clock, warmup_amplitude=SIM.warmup_amplitude, drift_per_hour=SIM.drift_per_hour)
    lp.switch(True)
    lp.set_current(NOMINAL_A)
    t_on = clock.now()
    assert lp.relative_output() == pytest.approx(1.0 + SIM.warmup_amplitude)
    at_tau = lp.relative_output(t_on + SIM.warmup_tau_s)
    assert at_tau == pytest.approx((1 + SIM.warmup_amplitude / math.e) * (1 + SIM.drift_per_hour * SIM.warmup_tau_s
                                                                         / 3600))
    assert lp.relative_output(t_on + 3600.0) == pytest.approx(1.0 + SIM.drift_per_hour, rel=1e-6)
    lp.switch(False)
    assert lp.relative_output() == 0.0
    clock.sleep(10.0)
    lp.switch(True)                                            # warm-up starts again at each switch-on
    assert lp.relative_output() == pytest.approx(1.0 + SIM.warmup_amplitude)


def test_voltage_limit_turns_constant_current_into_constant_voltage(clock):
    lp = lamp(clock)
    lp.set_compliance(6.0)
    warm(lp, NOMINAL_A)
    assert lp.voltage_v() == pytest.approx(6.0)
    current = lp.filament_current_a()
    assert current < NOMINAL_A
    assert current * lp.resistance_ohm() == pytest.approx(6.0)
    assert lp.resistance_ohm() == pytest.approx(lp.steady_resistance_ohm(current))
    assert lp.relative_output() == pytest.approx((current / NOMINAL_A) ** SIM.lamp_exponent)


def test_burn_out_opens_the_filament_and_replacement_restores_it(clock):
    lp = lamp(clock, warmup_amplitude=SIM.warmup_amplitude)
    lp.set_compliance(15.0)
    warm(lp, NOMINAL_A)
    lp.burn_out()
    assert lp.burnt_out
    assert lp.filament_current_a() == 0.0
    assert lp.voltage_v() == 15.0                         # open circuit: the supply sits at its limit
    assert lp.relative_output() == 0.0
    clock.sleep(60.0)
    lp.replace()
    assert not lp.burnt_out
    assert lp.resistance_ohm() == pytest.approx(lp.cold_resistance_ohm)    # a new lamp starts cold
    assert lp.filament_current_a() == pytest.approx(NOMINAL_A, abs=1e-12)
    assert lp.relative_output() == pytest.approx(1.0 + SIM.warmup_amplitude)   # and warms up again


def test_world_lamp_keeps_the_interface_of_the_camera_and_meter():
    """SimWorld builds it from the configuration; without a supply limit nothing changes for the light."""
    from rig.config.rigfile import RigConfig
    from rig.physics.brdf_models import get_model
    from rig.simulators.world import SimWorld

    world = SimWorld(RigConfig(), get_model("lambert"), {"kd": 0.5})
    world.lamp.set_current(4.17, 0)
    world.lamp.switch(True)
    world.clock.sleep(SIM.warmup_tau_s)
    expected = (1 + SIM.warmup_amplitude / math.e) * (1 + SIM.drift_per_hour * SIM.warmup_tau_s / 3600)
    assert world.lamp.output_on and world.lamp.current_a() == pytest.approx(4.17, abs=1e-12)
    assert world.illuminance_normal_lx() == pytest.approx(SIM.illuminance_normal_lx * expected)
