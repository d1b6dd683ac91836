"""rig.planning.estimate on its own: the warm-up rule's end times and the simulated lamp model's expectation."""

from __future__ import annotations

import pytest

from rig.config.campaign import Lamp
from rig.config.rigfile import RigConfig, SimulationConfig
from rig.planning.estimate import checks_end, model_warmup_s, warmup_estimate


def test_a_warm_up_ends_at_a_check_within_the_maximum():
    lamp = Lamp(warmup_min_s=300, warmup_max_s=600, warmup_check_s=60)
    assert [checks_end(lamp, s) for s in (0.0, 360.0, 361.0, 5000.0)] == [360.0, 360.0, 420.0, 600.0]


def test_a_noiseless_meter_stops_where_the_lamps_change_per_check_falls_below_the_threshold():
    sim = SimulationConfig(meter_noise_rel=0.0)        # output −5 % at switch-on, τ 120 s
    lamp = Lamp(warmup_min_s=0, warmup_check_s=60, warmup_stable_rel=0.002)
    # change over a check at t: 0.05·e^(−(t+5)/120)·(e^0.5 − 1)/E(t) < 0.002 first at t = 360 s (300: 0.0026)
    assert model_warmup_s(lamp, sim, ramp_s=5.0) == pytest.approx(360.0)


def test_the_meters_noise_lengthens_the_expected_warm_up_and_the_source_says_so():
    noisy = warmup_estimate(Lamp(), RigConfig())                 # the campaigns' rule, 0.2 % noise and threshold
    assert 400.0 < noisy.seconds < 480.0 and "simulated lamp's model" in noisy.source
