"""pylablib's Thorlabs filter-wheel class against our simulated FW102C, over a pseudo-terminal.

`pylablib.devices.Thorlabs.FW` (PyPI pylablib-lightweight, class `FW` in `Thorlabs/serial.py`) is what a
lab's own script would use: 115200 baud, lower-case commands + CR, each echo checked (`_validate_echo`),
replies read up to CR or LF with the prompt `>` stripped, and a reply containing `CMD_` or `Error` refused.
The wheel is the peer the rig's own driver meets (tests/drivers/test_fw102c_integration.py): rebuilt from
the FW102C manual Rev H 2014 p. 11; its moves spend rig time on the world's clock, not wall time.

Where pylablib and the manual part: pylablib never sends `baud`; a move of half the wheel or more goes
the long way round in two intermediate steps (`respect_bound`: it never crosses between the last position
and the first, the manual is silent about why one would); and `write` reads only the echo, so a refused
setting (`pos=9`) raises nothing there: the error line is flushed by the next query, and only the position
read back shows it (asked for a position the wheel lacks, `set_position` stops at an intermediate step and
returns it). A refused query raises `ThorlabsError` naming the wheel's `Command error` reply.
"""

from __future__ import annotations

import importlib.util
import re
import sys
from collections.abc import Iterator
from pathlib import Path

import pylablib.devices
import pytest

from rig.config.rigfile import RigConfig
from rig.physics.brdf_models import get_model
from rig.simulators.fw102c_peer import IDENTITY, FW102CPeer
from rig.simulators.world import SimWorld


def pylablib_fw() -> type:
    """pylablib's `Thorlabs.FW`, imported without `Thorlabs/__init__.py`: that also imports the Thorlabs camera
    module, which needs numba (not a dependency of pylablib-lightweight); `FW` in `serial.py` needs none."""
    name = "pylablib.devices.Thorlabs"
    if name not in sys.modules:
        folder = Path(pylablib.devices.__path__[0]) / "Thorlabs"
        spec = importlib.util.spec_from_file_location(name, folder / "__init__.py",
                                                      submodule_search_locations=[str(folder)])
        assert spec is not None
        sys.modules[name] = importlib.util.module_from_spec(spec)     # the package, its __init__ not run
    from pylablib.devices.Thorlabs.serial import FW
    return FW


@pytest.fixture
def world() -> SimWorld:
    return SimWorld(RigConfig(), get_model("lambert"), {"kd": 0.5})


@pytest.fixture
def peer(world) -> Iterator[FW102CPeer]:
    with FW102CPeer(world) as p:
        yield p


@pytest.fixture
def wheel(peer) -> Iterator:
    fw = pylablib_fw()((peer.path, 115200))
    yield fw
    fw.close()


def test_identity_position_count_and_settings(wheel, peer):
    assert wheel.get_id() == IDENTITY
    assert wheel.get_pcount() == wheel.pcount == 6 and wheel.get_position() == 1
    assert wheel.set_speed_mode("high") == "high" and peer.speed == 1
    assert wheel.set_trigger_mode("out") == "out" and peer.trigger == 1
    assert wheel.set_sensor_mode("off") == "off" and peer.sensors == 0
    assert wheel.get_settings() == {"pos": 1, "pcount": 6, "speed_mode": "high", "trigger_mode": "out",
                                    "sensors_mode": "off"}
    assert wheel.ask("baud?", "int") == 1                  # the manual's `baud?`, asked as a script would
    wheel.store_settings()
    assert peer.saved == {"pos": 1, "pcount": 6, "speed": 1, "trig": 1, "sensors": 0, "baud": 1}


def test_moves_and_pylablibs_long_way_round(wheel, peer, world):
    """1 → 3 is a move of two positions (slow: 2 s each); 3 → 6 is half the wheel, which pylablib splits into
    3 → 4 → 5 → 6 rather than risk crossing 6 ↔ 1 (the wheel itself would go 3 → 2 → 1 → 6 or the same way)."""
    t0 = world.clock.now()
    assert wheel.set_position(3) == 3 and peer.position == 3
    assert world.clock.now() - t0 == pytest.approx(4.0)
    assert wheel.set_position(6) == 6 and peer.position == 6
    assert world.clock.now() - t0 == pytest.approx(4.0 + 3 * 2.0)
    wheel.set_speed_mode("high")
    assert wheel.set_position(5) == 5 and world.clock.now() - t0 == pytest.approx(11.0)


@pytest.mark.parametrize("command, error", [("pos=9", "CMD_ARG_INVALID"), ("pos=x", "CMD_ARG_INVALID"),
                                            ("home?", "CMD_NOT_DEFINED")])
def test_a_refused_query_raises_pylablibs_error(wheel, peer, command, error):
    thorlabs_error = sys.modules["pylablib.devices.Thorlabs.base"].ThorlabsError
    with pytest.raises(thorlabs_error, match=re.escape(f"query {command} returned unexpected reply: "
                                                       f"b'Command error {error}'")):
        wheel.ask(command)
    assert wheel.get_position() == 1 and peer.position == 1


def test_a_refused_setting_passes_unnoticed_until_the_position_is_read(wheel, peer):
    """`write` checks the echo only. Asked for position 7 of 6, pylablib's long way round goes 1 → 3 → 5 (both
    taken) before `pos=7` is refused unseen: it returns 5, where the wheel stopped, and raises nothing."""
    wheel.write("pos=9")
    assert wheel.get_position() == 1 and peer.position == 1
    assert wheel.set_position(7) == 5 and peer.position == 5
