"""A meter reading in the dark (an underload: below the floor of its range) wherever one can happen: it is a
reading, not a device failure, but no E⊥ is made of it and the illuminance suspender does not clear on it."""

import math

import pytest

from rig.acquisition.suspenders import DeviceSilent, IlluminanceJump
from rig.config.campaign import Lamp as WarmUp
from rig.core.values import IlluminanceReading
from rig.drivers.interfaces import IlluminanceMeter
from rig.physics.illuminance import NoLightError, estimate_of_readings, underload_u

CAL = 1e9
#: A P-9710 underload on range 7 (floor 0.1 pA): the midpoint of [0, floor), flagged.
DARK = IlluminanceReading(0.5e-13 * CAL, 0.5e-13, CAL, range_index=7, floor_a=1e-13)
LIT = IlluminanceReading(5000.0, 5e-6, CAL, range_index=2)


class Meter(IlluminanceMeter):
    def __init__(self, *readings: IlluminanceReading):
        self.readings = list(readings)

    def identity(self) -> str:
        return "meter"

    def read(self) -> IlluminanceReading:
        return self.readings.pop(0)


def test_an_underload_is_a_rectangle_over_zero_to_the_floor():
    assert DARK.underload and not LIT.underload
    assert underload_u(1e-13) == pytest.approx(1e-13 / math.sqrt(12), rel=1e-12)


def test_a_batch_with_an_underload_makes_no_illuminance():
    """One dark reading among lit ones is enough: an E⊥ near the floor would divide luminances into noise."""
    est = estimate_of_readings([LIT, LIT], 10.0, 0.0, 0.0, (0.0,) * 8)
    assert est.value_lx == pytest.approx(5000.0)
    with pytest.raises(NoLightError) as err:
        estimate_of_readings([LIT, DARK, DARK], 10.0, 0.0, 0.0, (0.0,) * 8)
    assert str(err.value) == ("2 of 3 readings below the meter's floor (underload: less than 1e-13 A on range "
                              "7, E⊥ taken as 5e-05 ± 2.9e-05 lx): no light on the detector")


def test_each_reading_carries_the_u_of_its_range():
    """The range table is indexed by each reading's range: readings on a range with a 1 % certificate u carry
    it, fully correlated (it does not average down), readings of unknown range carry none."""
    table = (0.0, 0.0, 0.01, 0.0, 0.0, 0.0, 0.0, 0.0)
    on_range = estimate_of_readings([LIT, LIT], 10.0, 0.0, 0.0, table)
    unknown = IlluminanceReading(5000.0, 5e-6, CAL)
    assert on_range.u_stat_lx == pytest.approx(50.0, rel=1e-9)
    assert estimate_of_readings([unknown, unknown], 10.0, 0.0, 0.0, table).u_stat_lx == pytest.approx(0.0, abs=1e-9)


def test_the_illuminance_suspender_does_not_clear_in_the_dark():
    """Two dark readings agree perfectly: steadiness, but of darkness."""
    steady = WarmUp(warmup_check_s=60.0, warmup_stable_rel=0.002)
    jump = IlluminanceJump(Meter(DARK, DARK, LIT, LIT), 0.02, steady, 0.002, lambda s: None)
    assert jump.check() == "no light on the meter: E⊥ below its floor (5e-05 lx)"
    assert jump.check() is None


def test_a_silent_meter_that_answers_in_the_dark_has_answered():
    assert DeviceSilent("meter", Meter(DARK).read).check() is None
