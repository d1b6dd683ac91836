"""The simulated Oriental Motor AZ drive answers the captured Modbus RTU exchanges byte for byte.

Frames from the public sources digested in docs/modbus-drives.md (Oriental Motor Europe FAQ 0331 and captured
Modbus RTU scripts); sent raw, CRC included, over the peer's RTU-over-socket link, with no rig driver involved.
"""

import socket
import threading

import pytest
from modbus_rtu import crc16_modbus

from rig.config.rigfile import AxisConfig, RigConfig, SimulationConfig
from rig.physics.brdf_models import get_model
from rig.simulators.oriental_az_peer import OrientalAZPeer
from rig.simulators.world import SimWorld

h = bytes.fromhex
AXES = [(name, AxisConfig(limits_deg=(-180, 180), speed_deg_s=15, accel_deg_s2=30, settle_s=0.2))
        for name in ("arm_azimuth", "arm_polar")]


@pytest.fixture
def az(no_leaks_here):
    """Drive id 1 (and 2) with ten steps per degree, no backlash and no positioning noise: positions are exact."""
    world = SimWorld(RigConfig(simulation=SimulationConfig(positioning_sigma_deg=0.0, axis_zero_sigma_deg=0.0)),
                     get_model("lambert"), {"kd": 0.5})
    with OrientalAZPeer(world, AXES, framer="rtu", steps_per_degree=10.0, backlash_deg=0.0) as peer:
        host, port = peer.url.removeprefix("modbus-rtu://socket://").split(":")
        with socket.create_connection((host, int(port)), timeout=2.0) as link:
            def exchange(request: bytes, reply_length: int) -> bytes:
                link.sendall(request)
                data = b""
                while len(data) < reply_length:
                    chunk = link.recv(reply_length - len(data))
                    if not chunk:
                        break
                    data += chunk
                return data
            yield world, exchange


@pytest.fixture
def no_leaks_here():
    before = set(threading.enumerate())
    yield
    assert set(threading.enumerate()) == before


def test_status_at_power_on_is_ready(az):
    _, exchange = az
    assert exchange(h("01 03 00 7E 00 02 A4 13"), 9) == h("01 03 04 00 00 00 20 FB EB")


def test_direct_data_move_then_feedback_position(az):
    world, exchange = az
    move = h("01 10 00 58 00 10 20 00000000 00000001 000003E8 000007D0 000005DC 000005DC 000003E8 00000001 6D D1")
    assert exchange(move, 8) == h("01 10 00 58 00 10 40 16")
    world.clock.sleep(3.0)           # 1000 steps (100°) at 2 kHz and 1.5 kHz/s take 1.63 s, + 0.2 s settling
    assert exchange(h("01 03 00 CC 00 02 04 34"), 9) == h("01 03 04 00 00 03 E8 FA 8D")


def test_alarm_reset_maintenance_command_is_echoed(az):
    _, exchange = az
    assert exchange(h("01 06 01 81 00 01 19 DE"), 8) == h("01 06 01 81 00 01 19 DE")


def test_unserved_register_is_illegal_address(az):
    """0x0120 (the feedback position of one source, 0x00CC of the others) is not served: exception 02."""
    _, exchange = az
    read_0120 = h("01 03 01 20 00 02")
    assert exchange(read_0120 + crc16_modbus(read_0120), 5) == h("01 83 02 C0 F1")


def test_operation_data_table_is_not_modelled(az):
    """The official example writes operation data No. 0's position (0x1802); the peer models direct data
    operation only, and says so with exception 02 rather than pretending."""
    _, exchange = az
    assert exchange(h("01 10 18 02 00 02 04 FF FF FC 18 99 58"), 5) == h("01 90 02 CD C1")


def test_reply_crcs_are_right():
    for frame in (h("01 03 04 00 00 00 20 FB EB"), h("01 83 02 C0 F1"), h("01 90 02 CD C1")):
        assert crc16_modbus(frame[:-2]) == frame[-2:]
