"""Zaber's official library, zaber-motion, against our simulated daisy chain, as a lab's own script would use it.

`zaber_motion.ascii.Connection` (PyPI zaber-motion: a compiled core behind a Python layer) opens the chain
over loopback TCP (`open_tcp`, as a serial-to-Ethernet bridge) or a pseudo-terminal (`open_serial_port`),
numbers its requests with message ids and checks `:LRC` checksums both ways. The chain is the peer the rig's
own driver meets (tests/drivers/test_zaber_integration.py); here it runs on a wall clock 100 times faster
than wall time, because zaber-motion waits for IDLE in wall time.

What it sends (captured from zaber-motion 10.3, and asserted below): `detect_devices` broadcasts the
status poll `/0 0 00:00`, then reads `comm.packet.size.max` of every device; `identify()` reads the device
settings `deviceid`, `system.serial`, `version`, `version.build`, `device.hw.modified`,
`comm.command.packets.max`, `comm.word.size.max`, `get.settings.max`, `system.axiscount` and the axis
settings `resolution`, `peripheralid`, `peripheral.serial`, `peripheral.hw.modified`, then looks the
`deviceid` up in Zaber's device database. That database is online (api.zaber.io) or a local file: the
tests point it at a file that does not exist, so nothing leaves loopback and identification fails at
once, on the database and on nothing else (every request was answered OK). Without identification it
works in native units: µsteps, and speed data (µsteps/s × 1.6384).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from zaber_motion import Library
from zaber_motion.ascii import Connection
from zaber_motion.dto.device_db_source_type import DeviceDbSourceType
from zaber_motion.exceptions import DeviceDbFailedException

from rig.config.rigfile import AxisConfig, RigConfig, SimulationConfig
from rig.drivers.wallclock import WallClock
from rig.physics.brdf_models import get_model
from rig.simulators.world import SimWorld
from rig.simulators.zaber_peer import CYCLE_DIST, DEVICE_ID, SERIAL_BASE, ZaberPeer

AXIS = AxisConfig(limits_deg=(-90, 90), speed_deg_s=15, accel_deg_s2=30, settle_s=0.2)
LIMIT = CYCLE_DIST // 4
#: 0.001° (half the default backlash) in µsteps: the encoder lags the last travel by this.
LAG = round(0.001 * CYCLE_DIST / 360)


class RecordingPeer(ZaberPeer):
    """The chain, keeping every (request, reply) it exchanged."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.log: list[tuple[bytes, bytes | None]] = []

    def respond(self, line: bytes) -> bytes | None:
        reply = super().respond(line)
        self.log.append((line, reply))
        return reply


@pytest.fixture(autouse=True)
def offline_device_db(tmp_path: Path) -> None:
    """The device database: a local file that does not exist (no online look-up, no local store written)."""
    Library.set_device_db_source(DeviceDbSourceType.FILE, str(tmp_path / "no-device-db.sqlite"))
    Library.disable_device_db_store()


def chain(medium: str) -> RecordingPeer:
    world = SimWorld(RigConfig(simulation=SimulationConfig(positioning_sigma_deg=0.0, axis_zero_sigma_deg=0.0)),
                     get_model("lambert"), {"kd": 0.5}, clock=WallClock(100.0))
    return RecordingPeer(world, [(1, 1, "arm_azimuth", AXIS), (2, 1, "arm_polar", AXIS)], medium=medium)


@pytest.fixture
def tcp() -> Iterator[tuple[RecordingPeer, Connection]]:
    with chain("tcp") as peer:
        assert peer.url is not None
        host, port = peer.url.removeprefix("socket://").split(":")
        with Connection.open_tcp(host, int(port)) as connection:
            yield peer, connection


def refusals(peer: RecordingPeer) -> list[tuple[bytes, bytes | None]]:
    return [(request, reply) for request, reply in peer.log if reply is None or b" RJ " in reply]


def test_detect_home_and_move_in_native_units(tcp):
    peer, connection = tcp
    devices = connection.detect_devices(identify_devices=False)
    assert [d.device_address for d in devices] == [1, 2]
    # at power-up: no reference position (WR) until homed
    assert peer.log[0] == (b"/0 0 00:00", b"@01 0 00 OK IDLE WR 0:BE\r\n@02 0 00 OK IDLE WR 0:BD\r\n")
    axis = connection.get_device(2).get_axis(1)
    axis.home()
    assert axis.warnings.get_flags() == set()
    axis.move_absolute(100000)
    assert axis.get_position() == 100000                    # the target, exactly, once IDLE
    assert axis.settings.get("encoder.pos") == 100000 - LAG
    axis.move_relative(-4000)
    assert axis.get_position() == 96000
    axis.move_velocity(20000)
    axis.stop()
    stopped = axis.get_position()
    assert 96000 <= stopped < LIMIT
    axis.move_absolute(-LIMIT)
    assert axis.get_position() == -LIMIT
    assert axis.settings.get("maxspeed") == round(15 * CYCLE_DIST / 360 * 1.6384)
    axis.settings.set("maxspeed", 50000)
    assert axis.settings.get("maxspeed") == 50000
    assert refusals(peer) == []


def test_generic_commands_and_their_replies(tcp):
    peer, connection = tcp
    echo = connection.generic_command("tools echo hello", device=1)
    assert (echo.reply_flag, echo.status, echo.warning_flag, echo.data) == ("OK", "IDLE", "WR", "hello")
    serial = connection.generic_command("get system.serial", device=2)
    assert serial.data == str(SERIAL_BASE + 2)
    moving = connection.generic_command("move abs 200000", device=1, axis=1)
    assert moving.status == "BUSY"
    assert connection.generic_command("estop", device=1, axis=1).reply_flag == "OK"
    assert refusals(peer) == []


def test_identification_fails_only_on_the_unreachable_device_database(tcp):
    peer, connection = tcp
    connection.detect_devices(identify_devices=False)
    with pytest.raises(DeviceDbFailedException, match="Device Database"):
        connection.get_device(1).identify()
    asked = [request.split(b" ", 3)[-1].rsplit(b":", 1)[0] for request, _ in peer.log]
    assert {b"get deviceid", b"get system.serial", b"get comm.packet.size.max"} <= set(asked)
    assert refusals(peer) == []                             # not a protocol refusal: the database
    assert (b"@01 0 03 OK IDLE WR %d" % DEVICE_ID) in b"".join(reply or b"" for _, reply in peer.log)


def test_a_serial_port_chain_on_a_pseudo_terminal():
    with chain("pty") as peer, Connection.open_serial_port(peer.url) as connection:
        assert len(connection.detect_devices(identify_devices=False)) == 2
        axis = connection.get_device(1).get_axis(1)
        axis.home()
        axis.move_absolute(12345)
        assert axis.get_position() == 12345
        assert refusals(peer) == []
