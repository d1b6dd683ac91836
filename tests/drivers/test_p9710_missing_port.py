"""A meter port that does not exist (an unplugged adapter, a renamed one, a stopped `rig sim serve`'s pty) is
named as such (issue 30, smaller items). Before: the message asked whether the meter was in its "Remote RS232"
mode, a hint for a meter that is there but silent."""

import pytest

from rig.core.errors import DeviceError
from rig.drivers.p9710 import P9710


def test_a_missing_port_is_not_a_silent_meter(tmp_path, clock):
    missing = tmp_path / "ttyUSB9"                    # a device path no one created: nothing is opened
    with pytest.raises(DeviceError) as err:
        P9710(str(missing), calibration_lx_per_a=1e9, clock=clock, timeout_s=0.2)
    assert str(err.value) == (f"meter: connect failed 3 times; last: meter: cannot open {missing}: the port does not "
                              "exist (unplugged, renamed, or its server has stopped?)")
    assert err.value.unanswered
