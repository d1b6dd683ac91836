"""Generic Modbus drive driver: URLs, drive maps, and the exact request/reply PDUs, replayed in memory.

The Oriental Motor AZ exchanges below are the captured frames quoted in docs/modbus-drives.md (public
sources: Oriental Motor Europe FAQ 0331; the Modbus RTU scripts digested there), with the device id and CRC
stripped: the CRC of each captured frame is checked here too. The driver against the simulated drives over
TCP and RTU, with every fault, is in test_modbus_drive_integration.py.
"""

from importlib import resources

import pytest
from modbus_rtu import crc16_modbus

from rig.core.errors import DeviceError
from rig.drivers.modbus_drive import ModbusDriveLink, modbus_client
from rig.drivers.modbus_drive_map import DriveMapError, load_drive_map, packaged_maps
from rig.drivers.retry import RetryPolicy

h = bytes.fromhex
AZ = load_drive_map("oriental-az")
AZ_TEXT = resources.files("rig.drivers").joinpath("drive_maps", "oriental-az.yaml").read_text("utf-8")
#: Captured Modbus RTU frames of an AZ drive at id 1 (request, reply).
STATUS_READ = (h("01 03 00 7E 00 02 A4 13"), h("01 03 04 00 00 00 20 FB EB"))             # READY
POSITION_READ = (h("01 03 00 CC 00 02 04 34"), h("01 03 04 00 00 03 E8 FA 8D"))           # 1000 steps
DIRECT_MOVE = (h("01 10 00 58 00 10 20 00000000 00000001 000003E8 000007D0 000005DC 000005DC 000003E8 00000001"
                 " 6D D1"), h("01 10 00 58 00 10 40 16"))   # absolute to 1000 at 2 kHz, 1.5 kHz/s, 100 %, trigger 1
ILLEGAL_ADDRESS = h("01 83 02 C0 F1")


def pdu(frame: bytes) -> bytes:
    """The PDU of a captured RTU frame, whose CRC must be right."""
    assert crc16_modbus(frame[:-2]) == frame[-2:], frame.hex(" ")
    return frame[1:-2]


def replayed(replay, clock, *, speed_deg_s=2000.0, accel_deg_s2=1500.0, settle_s=0.0):
    """Drive id 1 with one step per degree, so the captured move's speed and rates are the rig file's."""
    link = ModbusDriveLink("modbus-rtu:///dev/ttyUSB0", AZ, name="arm", clock=clock, timeout_s=0.5,
                           retry=RetryPolicy(attempts=3, backoff_s=0.05), open_client=replay.open_client)
    return link, link.axis(1, "arm_azimuth", 1.0, speed_deg_s, accel_deg_s2, settle_s)


# -- transport and maps -------------------------------------------------------------------------
@pytest.mark.parametrize("url, cls, host", [
    ("modbus-tcp://10.0.0.5:502", "ModbusTcpClient", "10.0.0.5"),
    ("modbus-rtu://socket://127.0.0.1:5020", "ModbusSerialClient", "socket://127.0.0.1:5020"),
    ("modbus-rtu:///dev/ttyUSB0?baudrate=115200&parity=E", "ModbusSerialClient", "/dev/ttyUSB0"),
])
def test_url_selects_transport(url, cls, host):
    client = modbus_client(url, 1.0)
    assert type(client).__name__ == cls and client.comm_params.host == host


def test_rtu_defaults_are_the_az_factory_setting():
    params = modbus_client("modbus-rtu:///dev/ttyUSB0", 1.0).comm_params
    assert (params.baudrate, params.parity, params.bytesize, params.stopbits) == (115200, "E", 8, 1)


@pytest.mark.parametrize("url", ["tcp://host:502", "modbus-tcp://host", "modbus-rtu:///dev/ttyS0?speed=9600"])
def test_bad_url_is_refused(url):
    with pytest.raises(ValueError):
        modbus_client(url, 1.0)


def test_packaged_az_map_says_what_the_sources_say():
    assert "oriental-az" in packaged_maps()
    assert AZ.move.address == 0x0058 and AZ.move.values == [0, 1, "target", "speed", "accel", "decel", 1000, 1]
    assert (AZ.status.address, AZ.alarm_code.address, AZ.position.address) == (0x007E, 0x0080, 0x00CC)
    bits = AZ.status.bits
    assert (bits.ready, bits.alarm, bits.moving, bits.in_position) == (5, 7, 13, 14)
    assert {c.address for c in (AZ.commands.stop, AZ.commands.home, AZ.commands.alarm_reset)} == {0x0078}
    assert AZ.alarm_text(0x10).startswith("excessive position deviation") and "not in" in AZ.alarm_text(0x99)
    assert AZ.to_registers([1000, -1]) == [0, 1000, 0xFFFF, 0xFFFF]
    assert AZ.from_registers([0xFFFF, 0xFC18]) == [-1000]


def test_a_map_of_ones_own_is_a_file(tmp_path):
    text = AZ_TEXT
    own = tmp_path / "my-drive.yaml"
    own.write_text(text.replace("Oriental Motor AZ series", "My drive").replace("word_order: big",
                                                                                   "word_order: little"))
    mine = load_drive_map(str(own))
    assert mine.drive == "My drive" and mine.to_registers([1000]) == [1000, 0]


@pytest.mark.parametrize("edit, message", [
    (lambda t: t.replace("0x0058", "-1"), "key 'move.address'"),
    (lambda t: t.replace("target,   ", ""), "key 'move': Value error, values must name 'target' exactly once"),
    (lambda t: t.replace("  stop: {address: 0x0078, value: 0x0020}", ""), "key 'commands.stop': Field required"),
    (lambda t: t + "\nextra: 1\n", "key 'extra': Extra inputs are not permitted"),
    (lambda t: t.replace("move:", "move: [", 1), "not valid YAML"),
])
def test_a_broken_map_is_refused_naming_file_and_key(tmp_path, edit, message):
    text = AZ_TEXT
    broken = tmp_path / "broken.yaml"
    broken.write_text(edit(text))
    with pytest.raises(DriveMapError) as err:
        load_drive_map(str(broken))
    assert str(err.value).startswith(str(broken)) and message in str(err.value)


def test_unknown_map_name_lists_the_packaged_ones():
    with pytest.raises(DriveMapError, match=r"'fancy-drive': no such packaged map \(known: .*oriental-az"):
        load_drive_map("fancy-drive")


# -- exact exchanges ----------------------------------------------------------------------------
def test_captured_exchanges_replayed(expected_protocol, clock):
    """Status at rest, feedback position, and the captured direct-data move, byte for byte."""
    exchanges = [(pdu(request), pdu(reply)) for request, reply in (STATUS_READ, POSITION_READ, DIRECT_MOVE)]
    with expected_protocol(exchanges) as replay:
        _, axis = replayed(replay, clock)
        state = axis.state()
        assert state.ready and not (state.moving or state.in_position or state.alarm)
        assert axis.position_deg() == pytest.approx(1000.0)
        axis.start_move(1000.0)          # from where the read-back says: no further read


def test_a_move_is_fc16_then_fc3_never_fc23(expected_protocol, clock):
    """Move from an unknown position: read it, write the move block, sleep the predicted time, poll the status
    once (READY | IN-POS), read back."""
    in_position = h("03 04 0000 4020")
    exchanges = [(pdu(POSITION_READ[0]), h("03 04 0000 0000")), (pdu(DIRECT_MOVE[0]), pdu(DIRECT_MOVE[1])),
                 (pdu(STATUS_READ[0]), in_position), (pdu(POSITION_READ[0]), pdu(POSITION_READ[1]))]
    with expected_protocol(exchanges, now=clock.now) as replay:
        _, axis = replayed(replay, clock)
        axis.start_move(1000.0)
        axis.wait()
        assert axis.position_deg() == pytest.approx(1000.0)
    assert {request[0] for request, _ in replay.written} == {0x03, 0x10}
    predicted = axis.move_time_s(0.0, 1000.0)
    assert replay.written[2][1] == pytest.approx(predicted, abs=1e-5)       # the poll came at the predicted time


def test_the_prediction_is_of_the_move_in_whole_steps_so_one_poll_does(expected_protocol, clock):
    """999.6° goes out as 1000 steps: the drive runs 0.4 step further than asked, and the poll waits for that
    (a prediction for 999.6° would poll too early and need a second poll, a poll interval later)."""
    exchanges = [(pdu(POSITION_READ[0]), h("03 04 0000 0000")), (pdu(DIRECT_MOVE[0]), pdu(DIRECT_MOVE[1])),
                 (pdu(STATUS_READ[0]), h("03 04 0000 4020"))]
    with expected_protocol(exchanges, now=clock.now) as replay:
        _, axis = replayed(replay, clock)
        axis.start_move(999.6)
        axis.wait()
    assert replay.written[2][1] == pytest.approx(axis.move_time_s(0.0, 1000.0), abs=1e-5)


def test_stop_home_and_alarm_reset_are_pulses_of_the_auto_off_input(expected_protocol, clock):
    exchanges = [(h("10 0078 0002 04 0000 0020"), h("10 0078 0002")),       # STOP
                 (h("10 0078 0002 04 0000 0080"), h("10 0078 0002")),       # ALM-RST
                 (pdu(POSITION_READ[0]), pdu(POSITION_READ[1])),            # home: from where?
                 (h("10 0078 0002 04 0000 0010"), h("10 0078 0002")),       # ZHOME
                 (pdu(STATUS_READ[0]), h("03 04 0000 4020"))]
    with expected_protocol(exchanges, now=clock.now) as replay:
        _, axis = replayed(replay, clock)
        axis.stop()
        axis.reset_alarm()
        axis.home()


def test_alarm_reads_its_code_and_names_it(expected_protocol, clock):
    exchanges = [(pdu(STATUS_READ[0]), h("03 04 0000 00A0")),                # READY | ALM-A
                 (h("03 0080 0002"), h("03 04 0000 0010"))]
    with expected_protocol(exchanges, now=clock.now) as replay:
        _, axis = replayed(replay, clock)
        with pytest.raises(DeviceError, match=r"arm_azimuth: move: alarm 0x10 \(excessive position deviation") as err:
            axis.wait()
    assert not err.value.transient


def test_no_reply_is_retried_after_a_reconnect_with_the_same_request(expected_protocol, clock, events):
    request = pdu(POSITION_READ[0])
    with expected_protocol([(request, None), (request, pdu(POSITION_READ[1]))]) as replay:
        link, axis = replayed(replay, clock)
        link.events = lambda kind, **fields: events.append((kind, fields))
        assert axis.position_deg() == pytest.approx(1000.0)
    assert [kind for kind, _ in events] == ["retry", "reconnect"]
    assert replay.opens == 2


def test_exception_reply_is_persistent_and_names_drive_register_and_code(expected_protocol, clock):
    with expected_protocol([(pdu(POSITION_READ[0]), pdu(ILLEGAL_ADDRESS))]) as replay:
        _, axis = replayed(replay, clock)
        with pytest.raises(DeviceError) as err:
            axis.position_deg()
    assert str(err.value) == ("arm_azimuth: Oriental Motor AZ series drive (Modbus id 1 at modbus-rtu:///dev/ttyUSB0): "
                              "read feedback position at register 0x00CC answered Modbus exception 0x02 "
                              "(illegal data address)")
    assert not err.value.transient


@pytest.mark.parametrize("code, name", [(0x0A, "gateway path unavailable"),
                                        (0x0B, "gateway target device failed to respond")])
def test_a_gateways_exception_is_retried_like_a_timeout(expected_protocol, clock, events, code, name):
    """Behind a Modbus/TCP gateway, a drive that did not answer on the RS-485 side comes back as exception
    0Ah/0Bh: the same silence as an RTU timeout, retried after a reconnect, the event naming the exception."""
    request = pdu(POSITION_READ[0])
    with expected_protocol([(request, bytes([0x83, code])), (request, pdu(POSITION_READ[1]))]) as replay:
        link, axis = replayed(replay, clock)
        link.events = lambda kind, **fields: events.append((kind, fields))
        assert axis.position_deg() == pytest.approx(1000.0)
    assert [kind for kind, _ in events] == ["retry", "reconnect"]
    assert events[0][1]["error"].endswith(f"register 0x00CC answered Modbus exception 0x{code:02X} ({name})")


def test_a_gateway_that_keeps_answering_0B_ends_in_one_message(expected_protocol, clock):
    request = pdu(POSITION_READ[0])
    with expected_protocol([(request, h("83 0B"))] * 3) as replay:
        _, axis = replayed(replay, clock)
        with pytest.raises(DeviceError) as err:
            axis.position_deg()
    assert str(err.value) == ("arm_azimuth: read feedback position failed 3 times; last: arm_azimuth: Oriental Motor "
                              "AZ series drive (Modbus id 1 at modbus-rtu:///dev/ttyUSB0): read feedback position at "
                              "register 0x00CC answered Modbus exception 0x0B (gateway target device failed to "
                              "respond)")
    assert not err.value.transient


@pytest.mark.parametrize("code, name", [(0x01, "illegal function"), (0x03, "illegal data value"),
                                        (0x04, "server device failure"), (0x06, "server device busy"),
                                        (0x0C, "not a standard exception code")])
def test_any_other_exception_is_one_persistent_error(expected_protocol, clock, events, code, name):
    with expected_protocol([(pdu(POSITION_READ[0]), bytes([0x83, code]))]) as replay:
        link, axis = replayed(replay, clock)
        link.events = lambda kind, **fields: events.append((kind, fields))
        with pytest.raises(DeviceError, match=rf"0x00CC answered Modbus exception 0x{code:02X} \({name}\)$") as err:
            axis.position_deg()
    assert not err.value.transient and events == []
