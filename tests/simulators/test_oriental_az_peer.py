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
            def exchange(request: bytes, reply_length: int, timeout_s: float = 2.0) -> bytes:
                """Whatever comes back within `timeout_s`, up to `reply_length` bytes."""
                link.sendall(request)
                link.settimeout(timeout_s)
                data = b""
                while len(data) < reply_length:
                    try:
                        chunk = link.recv(reply_length - len(data))
                    except TimeoutError:
                        break
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


def test_operation_data_no_0_position_is_written_and_read_back(az):
    """The maker's FAQ 0331 frame writes operation data No. 0's position (0x1802) = -1000: the write is echoed,
    and the position reads back as written."""
    _, exchange = az
    assert exchange(h("01 10 18 02 00 02 04 FF FF FC 18 99 58"), 8) == h("01 10 18 02 00 02 E6 A8")
    assert exchange(h("01 03 18 02 00 02 63 6B"), 9) == h("01 03 04 FF FF FC 18 BB 1D")


def test_operation_data_area_ends_after_no_255(az):
    """0x1800 + 256 x 0x40 registers: a read that runs past 0x57FF is an illegal address."""
    _, exchange = az
    assert exchange(h("01 03 57 FE 00 04 35 8D"), 5) == h("01 83 02 C0 F1")


def test_feedback_position_and_speeds_during_a_move(az):
    """0x00CC-0x00D1 in one read, 0.4 s into the captured move (1000 steps, 2 kHz, 1.5 kHz/s: still
    accelerating): 120 steps, 600 Hz, and 36 r/min at the factory 1000 steps per motor revolution."""
    world, exchange = az
    move = h("01 10 00 58 00 10 20 00000000 00000001 000003E8 000007D0 000005DC 000005DC 000003E8 00000001 6D D1")
    assert exchange(move, 8) == h("01 10 00 58 00 10 40 16")
    world.clock.sleep(0.4)
    reply = h("01 03 0C 00000078 00000024 00000258")
    assert exchange(h("01 03 00 CC 00 06 05 F7"), 17) == reply + crc16_modbus(reply)


def test_an_absent_unit_is_silent_on_rtu(az):
    """Nothing at id 5 on the bus: no reply at all (there was exception 04), and the bus stays usable."""
    _, exchange = az
    assert exchange(h("05 03 00 7E 00 02 A5 97"), 5, timeout_s=0.3) == b""
    assert exchange(h("01 03 00 7E 00 02 A4 13"), 9) == h("01 03 04 00 00 00 20 FB EB")


@pytest.mark.parametrize("request_pdu, reply_pdu", [
    ("08 0000 1234", "08 0000 1234"),          # diagnostics, return query data: the echo
    ("08 0001 0000", "88 01"),                 # other diagnostics: not the drive's
    ("04 00CC 0002", "84 01"),                 # read input registers
    ("17 007E 0002 0078 0002 04 0000 0000", "97 01"),      # read/write multiple registers (FC 23)
])
def test_function_codes_are_those_of_the_drive(az, request_pdu, reply_pdu):
    """FC 03, 06, 08 (echo) and 10h are served; any other is exception 01 (illegal function)."""
    _, exchange = az
    request, reply = h("01" + request_pdu), h("01" + reply_pdu)
    assert exchange(request + crc16_modbus(request), len(reply) + 2) == reply + crc16_modbus(reply)


def test_reply_crcs_are_right():
    for frame in (h("01 03 04 00 00 00 20 FB EB"), h("01 83 02 C0 F1"), h("01 10 18 02 00 02 E6 A8"),
                  h("01 03 04 FF FF FC 18 BB 1D")):
        assert crc16_modbus(frame[:-2]) == frame[-2:]
