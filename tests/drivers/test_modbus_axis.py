"""Modbus axis driver: register conversions, URLs, and the exact request/reply PDUs, replayed in memory
and checked against the simulated controller's own replies.

The driver against the simulated controller over TCP and RTU, with every fault, is in
test_modbus_axis_integration.py.
"""

import pytest

from rig.config.rigfile import AxisConfig, RigConfig, SimulationConfig
from rig.core.errors import DeviceError
from rig.drivers.interfaces import TwoAxisPositioner
from rig.drivers.modbus_axis import ModbusAxisController, modbus_client
from rig.drivers.modbus_axis_map import int32_to_regs, regs_to_int32, regs_to_text, text_to_regs
from rig.drivers.retry import RetryPolicy
from rig.physics.brdf_models import get_model
from rig.simulators.clock import SimClock
from rig.simulators.modbus_axis_server import ModbusAxisServer
from rig.simulators.world import SimWorld

ARM = [(name, AxisConfig(limits_deg=(-180, 180), speed_deg_s=15, accel_deg_s2=30, settle_s=0.2))
       for name in ("arm_azimuth", "arm_polar")]
h = bytes.fromhex
#: `move_to(150.0, -12.345)` and the read-backs: Modbus/TCP PDUs (header stripped), request then reply.
MOVE_REQUESTS = [
    # FC 23: read STATUS..COMMAND_POS of axis 0, write TARGET 150000, SPEED 15000, ACCEL 30000, START
    h("17 0108 0008 0100 0008 10 0002 49F0 0000 3A98 0000 7530 0000 0001"),
    # axis 1, target -12345 steps
    h("17 0208 0008 0200 0008 10 FFFF CFC7 0000 3A98 0000 7530 0000 0001"),
    h("03 0108 0008"),          # one status poll per axis after the predicted move time
    h("03 0208 0008"),
    h("03 010C 0002"),          # encoder read-backs
    h("03 020C 0002"),
]
MOVE_REPLIES = [
    # BUSY, no alarm, encoder -1 step (load behind by the backlash), command position 0
    h("17 10 0000 0002 0000 0000 FFFF FFFF 0000 0000"),
    h("17 10 0000 0002 0000 0000 FFFF FFFF 0000 0000"),
    h("03 10 0000 0005 0000 0000 0002 49EF 0002 49F0"),     # READY|IN_POSITION, 149999, 150000
    h("03 10 0000 0005 0000 0000 FFFF CFC8 FFFF CFC7"),     # -12344, -12345
    h("03 04 0002 49EF"),
    h("03 04 FFFF CFC8"),
]


def axes_of(controller: ModbusAxisController) -> list:
    return [controller.axis(i, n, 1000.0, c.speed_deg_s, c.accel_deg_s2, c.settle_s) for i, (n, c) in enumerate(ARM)]


def move_and_read_back(axes: list) -> None:
    azimuth, polar = axes
    TwoAxisPositioner("arm", azimuth, polar).move_to(150.0, -12.345)
    assert azimuth.position_deg() == pytest.approx(149.999, abs=1e-9)      # encoder steps / 1000
    assert polar.position_deg() == pytest.approx(-12.344, abs=1e-9)


# -- conversions ------------------------------------------------------------------------------
def test_int32_upper_word_first():
    assert int32_to_regs(0x12345678, -2, 150000) == [0x1234, 0x5678, 0xFFFF, 0xFFFE, 0x0002, 0x49F0]
    assert regs_to_int32([0xFFFF, 0xCFC7, 0x8000, 0x0000]) == [-12345, -2 ** 31]
    assert regs_to_text(text_to_regs("SIM-2AX", 8)) == "SIM-2AX"
    assert text_to_regs("AB", 2) == [0x4142, 0]


@pytest.mark.parametrize("url, cls, host", [
    ("modbus-tcp://10.0.0.5:502", "ModbusTcpClient", "10.0.0.5"),
    ("modbus-rtu://socket://127.0.0.1:5020", "ModbusSerialClient", "socket://127.0.0.1:5020"),
    ("modbus-rtu:///dev/ttyUSB0?baudrate=115200&parity=E", "ModbusSerialClient", "/dev/ttyUSB0"),
])
def test_url_selects_transport(url, cls, host):
    client = modbus_client(url, 1.0)
    assert type(client).__name__ == cls and client.comm_params.host == host


@pytest.mark.parametrize("url", ["tcp://host:502", "modbus-tcp://host", "modbus-rtu:///dev/ttyS0?speed=9600"])
def test_bad_url_is_refused(url):
    with pytest.raises(ValueError):
        modbus_client(url, 1.0)


# -- exact register exchanges -----------------------------------------------------------------
def replayed_controller(replay, clock: SimClock) -> ModbusAxisController:
    return ModbusAxisController("modbus-tcp://arm:502", name="arm", clock=clock, timeout_s=0.5,
                                retry=RetryPolicy(attempts=3, backoff_s=0.05), open_client=replay.open_client)


def test_register_exchanges_replayed(expected_protocol):
    with expected_protocol(list(zip(MOVE_REQUESTS, MOVE_REPLIES))) as replay:
        move_and_read_back(axes_of(replayed_controller(replay, SimClock())))
    assert [request for request, _ in replay.written] == MOVE_REQUESTS


def test_register_exchanges_recorded_from_the_simulated_controller():
    """The simulated controller answers the driver's requests with exactly the replayed replies."""
    world = SimWorld(RigConfig(simulation=SimulationConfig(positioning_sigma_deg=0.0, axis_zero_sigma_deg=0.0)),
                     get_model("lambert"), {"kd": 0.5})
    frames: dict[bool, list[bytes]] = {True: [], False: []}

    def record(sending: bool, frame: bytes) -> bytes:
        if len(frame) >= 6 and len(frame) == 6 + int.from_bytes(frame[4:6], "big"):    # a whole frame
            frames[sending].append(frame[7:])
        return frame

    def recording_client(url: str, timeout_s: float):
        client = modbus_client(url, timeout_s)
        client.transaction.trace_packet = record
        return client

    with ModbusAxisServer(world, ARM) as server:
        controller = ModbusAxisController(server.url, name="arm", clock=world.clock, timeout_s=0.5,
                                          open_client=recording_client)
        move_and_read_back(axes_of(controller))
        controller.close()
    assert frames[True] == MOVE_REQUESTS
    assert frames[False] == MOVE_REPLIES


def test_no_reply_is_retried_after_a_reconnect_with_the_same_request(expected_protocol):
    encoder = h("03 010C 0002")
    with expected_protocol([(encoder, None), (encoder, h("03 04 0002 49EF"))]) as replay:
        controller = replayed_controller(replay, SimClock())
        events = []
        controller.events = lambda kind, **fields: events.append((kind, fields))
        assert axes_of(controller)[0].position_deg() == pytest.approx(149.999, abs=1e-9)
    assert [kind for kind, _ in events] == ["retry", "reconnect"]
    assert replay.opens == 2


def test_exception_reply_is_persistent_and_names_register_and_code(expected_protocol):
    with expected_protocol([(h("03 010C 0002"), h("83 04"))]) as replay:
        controller = replayed_controller(replay, SimClock())
        with pytest.raises(DeviceError) as err:
            axes_of(controller)[0].position_deg()
    assert str(err.value) == ("arm_azimuth: controller 'arm': read encoder position at register 0x010C "
                              "(id 1, modbus-tcp://arm:502) answered Modbus exception 4 (device failure)")
    assert not err.value.transient
