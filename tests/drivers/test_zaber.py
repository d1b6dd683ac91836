"""Zaber ASCII driver: the exact byte exchanges, replayed in memory.

Provenance of the bytes (public sources): the Zaber ASCII protocol manual (zaber.com/protocol-manual,
zaber.com/wiki/Manuals/ASCII_Protocol_Manual: `/d a command[:LRC]`, replies `@dd a OK|RJ BUSY|IDLE FLAG data`
+ CRLF, `warnings` answering a count then the flags, `RJ` reasons), the Zaber article's constructed examples
(zaber.com/articles/ascii-protocol: `@01 0 OK BUSY -- 0`), github stphnt/zproto src/ascii/checksum.rs tests
(`/1:CF`, `/1 tools echo:BF`, `/get maxspeed:49`), zaber-motion's warning_flags.py (flag names), and the A/X-series
unit conversions (maxspeed data = µsteps/s × 1.6384, accel data = µsteps/s² × 1.6384 / 10000). No real captures
were found. The driver against the rebuilt peer, with every fault, is in test_zaber_integration.py.
"""

import re

import pytest
from shared import ZABER_CONNECT as CONNECT
from shared import Exchange, Replay, ReplayPort

from rig.config.rigfile import AxisConfig
from rig.core.errors import DeviceError
from rig.core.motion import move_time_s
from rig.drivers.retry import RetryPolicy
from rig.drivers.zaber import FLAGS, ZaberAxis, ZaberChain, lrc

PER_DEG = 1536000 / 360
#: Axis 1 of device 1 at power-up: 1 536 000 µsteps per turn, no reference, and another speed and acceleration
#: than the rig file's (15 °/s → 104858, 30 °/s² → 21): the driver reads them, then sets them.
CONNECT_UNHOMED = [
    (b"/1 1 get limit.cycle.dist:BF\n", b"@01 1 OK IDLE WR 1536000\r\n"),
    (b"/1 1 get maxspeed:A7\n", b"@01 1 OK IDLE WR 153600\r\n"),
    (b"/1 1 set maxspeed 104858:41\n", b"@01 1 OK IDLE WR 0\r\n"),
    (b"/1 1 get accel:06\n", b"@01 1 OK IDLE WR 205\r\n"),
    (b"/1 1 set accel 21:77\n", b"@01 1 OK IDLE WR 0\r\n"),
    (b"/1 1 warnings:F5\n", b"@01 1 OK IDLE WR 01 WR:43\r\n"),
]
GET_POS = b"/1 1 get pos:AC\n"
MOVE_30 = b"/1 1 move abs 128000:06\n"          # 30° = 128 000 µsteps
POLL = b"/1 1:7E\n"
WARNINGS = b"/1 1 warnings:F5\n"
IDLE = b"@01 1 OK IDLE -- 0\r\n"
BUSY = b"@01 1 OK BUSY -- 0\r\n"
NO_WARNINGS = b"@01 1 OK IDLE -- 00\r\n"
SPEED, ACCEL = 104858 / 1.6384 / PER_DEG, 21 / (1.6384 / 10000) / PER_DEG      # what the device runs
SETTLE = 0.2


def line(body: str, prefix: str = "@") -> bytes:
    """A message with its LRC (computed here independently of the driver) and terminator."""
    check = (256 - sum(body.encode()) % 256) % 256
    return f"{prefix}{body}:{check:02X}".encode() + (b"\r\n" if prefix == "@" else b"\n")


class LinePort(ReplayPort):
    """A replay port that hands out a scripted reply line by line (info and alert lines before the reply)."""

    def read_until(self, expected: bytes = b"\n", size: int | None = None) -> bytes:
        if self._pending is None or b"\n" not in self._pending:
            return super().read_until(expected, size)
        first, rest = self._pending.split(b"\n", 1)
        self._pending = rest or None
        return first + b"\n"


def chain(open_port, clock, events) -> ZaberChain:
    c = ZaberChain("/dev/ttyUSB0", name="arm", clock=clock, timeout_s=0.2, open_port=open_port,
                   retry=RetryPolicy(attempts=3, backoff_s=0.05))
    c.events = lambda kind, **fields: events.append((kind, fields))
    return c


def axis(open_port, clock, events, **options) -> ZaberAxis:
    return chain(open_port, clock, events).axis(1, 1, "arm_azimuth", 15.0, 30.0, SETTLE, **options)


def test_checksums_match_the_published_examples():
    assert (lrc("1"), lrc("1 tools echo"), lrc("get maxspeed")) == ("CF", "BF", "49")
    assert line("1", "/") == b"/1:CF\n"


def test_connect_reads_the_microstep_size_and_leaves_speed_and_acceleration_that_match(expected_protocol, clock,
                                                                                      events):
    """`set maxspeed`/`set accel` write the device's flash: a device that already has the rig file's values
    is only read."""
    with expected_protocol(CONNECT) as replay:
        ax = axis(replay.open_port, clock, events)
    assert ax.microsteps_per_degree == PER_DEG and ax.homed
    assert ax.speed_deg_s == pytest.approx(15.0, rel=1e-5) and ax.accel_deg_s2 == pytest.approx(30.0, rel=0.01)
    assert ax.identity() == "Zaber device 1 axis 1 on /dev/ttyUSB0" and events == []


@pytest.mark.parametrize("differs", ["maxspeed", "accel"])
def test_connect_sets_only_the_speed_or_acceleration_that_differs(expected_protocol, clock, events, differs):
    """The power-up script (CONNECT_UNHOMED) sets both; here one of them already matches."""
    read, other, write = {"maxspeed": (1, b"@01 1 OK IDLE -- 104857\r\n", b"/1 1 set maxspeed 104858:41\n"),
                          "accel": (2, b"@01 1 OK IDLE -- 22\r\n", b"/1 1 set accel 21:77\n")}[differs]
    script = [*CONNECT[:read], (CONNECT[read][0], other), (write, IDLE), *CONNECT[read + 1:]]
    with expected_protocol(script) as replay:
        axis(replay.open_port, clock, events)
    assert [request for request, _ in replay.written].count(write) == 1


def test_move_sleeps_the_predicted_time_polls_idle_and_reads_the_position(expected_protocol, clock, events):
    """The IDLE reply's flag field is `--`: no flag at all, so no `warnings` request follows it."""
    script = CONNECT + [(GET_POS, b"@01 1 OK IDLE -- 0\r\n"), (MOVE_30, BUSY), (POLL, IDLE),
                        (GET_POS, b"@01 1 OK IDLE -- 127996\r\n")]
    with expected_protocol(script, now=clock.now) as replay:
        ax = axis(replay.open_port, clock, events)
        ax.start_move(30.0)
        ax.wait()
        assert ax.position_deg() == pytest.approx(127996 / PER_DEG)
    predicted = move_time_s(30.0, SPEED, ACCEL) + SETTLE
    assert ax.move_time_s(0.0, 30.0) == pytest.approx(predicted)
    assert replay.written[-2][1] == pytest.approx(predicted, abs=1e-5)      # one poll, after the prediction
    assert events == []


def test_a_busy_poll_is_followed_by_another_after_poll_s(expected_protocol, clock, events):
    script = CONNECT + [(GET_POS, b"@01 1 OK IDLE -- 128000\r\n"), (b"/1 1 move abs 0:01\n", BUSY),
                        (POLL, BUSY), (POLL, IDLE)]
    with expected_protocol(script, now=clock.now) as replay:
        ax = axis(replay.open_port, clock, events)
        ax.start_move(0.0)
        ax.wait()
    first, second = replay.written[-2][1], replay.written[-1][1]
    assert second - first == pytest.approx(ZaberAxis.poll_s)


def test_a_move_that_outlasts_its_timeout_is_an_error(expected_protocol, clock, events):
    script = CONNECT + [(GET_POS, IDLE), (MOVE_30, BUSY), (POLL, BUSY)]
    with expected_protocol(script, now=clock.now) as replay:
        ax = axis(replay.open_port, clock, events)
        ax.start_move(30.0)
        with pytest.raises(DeviceError, match=r"^arm_azimuth: move not finished after 0\.04 s \(device 1 axis 1 "
                                              r"on /dev/ttyUSB0 BUSY\)$"):
            ax.wait(timeout_s=0.04)


@pytest.mark.parametrize("reason, meaning", [
    ("BADDATA", "parameter missing or out of range"), ("BADCOMMAND", "unknown command"),
    ("STATUSBUSY", "not allowed while moving")])
def test_a_rejection_is_persistent_and_names_command_and_reason(expected_protocol, clock, events, reason, meaning):
    script = CONNECT + [(GET_POS, IDLE), (MOVE_30, f"@01 1 RJ IDLE -- {reason}\r\n".encode())]
    with expected_protocol(script) as replay:
        ax = axis(replay.open_port, clock, events)
        with pytest.raises(DeviceError) as err:
            ax.start_move(30.0)
    assert str(err.value) == f"arm_azimuth: '/1 1 move abs 128000:06' rejected: {reason} ({meaning})"
    assert not err.value.transient and events == []


@pytest.mark.parametrize("flag", ["FS", "FE", "FQ", "WL", "WS", "WM"])
def test_a_fault_or_warning_flag_ends_the_wait_with_its_meaning(expected_protocol, clock, events, flag):
    script = CONNECT + [(GET_POS, IDLE), (MOVE_30, BUSY), (POLL, f"@01 1 OK IDLE {flag} 0\r\n".encode())]
    with expected_protocol(script) as replay:
        ax = axis(replay.open_port, clock, events)
        ax.start_move(30.0)
        with pytest.raises(DeviceError) as err:
            ax.wait()
    assert str(err.value) == (f"arm_azimuth: status poll: device 1 axis 1 on /dev/ttyUSB0 flags {flag} "
                              f"({FLAGS[flag]}); `warnings clear` after fixing the cause")
    assert not err.value.transient


def test_flags_below_the_highest_are_found_by_the_warnings_after_the_move(expected_protocol, clock, events):
    script = CONNECT + [(GET_POS, IDLE), (MOVE_30, BUSY), (POLL, b"@01 1 OK IDLE NI 0\r\n"),
                        (WARNINGS, b"@01 1 OK IDLE NI 02 NI WL\r\n")]
    with expected_protocol(script) as replay:
        ax = axis(replay.open_port, clock, events)
        ax.start_move(30.0)
        with pytest.raises(DeviceError, match=r"after the move: .* flags WL \(unexpected limit trigger\)"):
            ax.wait()
    assert [(k, f["flag"]) for k, f in events] == [("warning", "NI (movement interrupted)")] * 2


def test_notices_are_events_not_errors(expected_protocol, clock, events):
    with expected_protocol(CONNECT + [(GET_POS, b"@01 1 OK IDLE NR 5\r\n")]) as replay:
        assert axis(replay.open_port, clock, events).position_deg() == pytest.approx(5 / PER_DEG)
    assert events == [("warning", {"device": "arm_azimuth", "what": "get pos", "flag": "NR (value rounded)"})]


def test_an_axis_without_reference_refuses_moves_until_homed(expected_protocol, clock, events):
    script = CONNECT_UNHOMED + [
        (b"/1 1 home:B5\n", line("01 1 OK BUSY WR 0")), (POLL, b"@01 1 OK BUSY WR 0\r\n"), (POLL, IDLE),
        (MOVE_30, BUSY)]
    with expected_protocol(script) as replay:
        ax = axis(replay.open_port, clock, events)
        assert not ax.homed and events == []            # WR at power-up is expected, not an error
        with pytest.raises(DeviceError, match=r"^arm_azimuth: device 1 axis 1 on /dev/ttyUSB0 has no reference "
                                              r"position \(WR/WH after power-up\): home it before moving$"):
            ax.start_move(30.0)
        ax.home()
        assert ax.homed
        ax.start_move(30.0)                              # from 0 after homing: no position read needed


def test_homing_that_leaves_no_reference_is_an_error(expected_protocol, clock, events):
    script = CONNECT_UNHOMED + [(b"/1 1 home:B5\n", b"@01 1 OK BUSY WR 0\r\n"), (POLL, b"@01 1 OK IDLE WR 0\r\n"),
                                (WARNINGS, b"@01 1 OK IDLE WR 01 WR\r\n")]
    with expected_protocol(script) as replay:
        ax = axis(replay.open_port, clock, events)
        with pytest.raises(DeviceError, match=r"homing ended without a reference position: .* flags WR "
                                              r"\(no reference position\)"):
            ax.home()
    assert not ax.homed


def test_a_lost_reference_on_a_homed_axis_is_an_error(expected_protocol, clock, events):
    """A power cycle of one device of the chain: its replies carry WR again."""
    with expected_protocol(CONNECT + [(GET_POS, b"@01 1 OK IDLE WR 0\r\n")]) as replay:
        ax = axis(replay.open_port, clock, events)
        with pytest.raises(DeviceError, match=r"get pos: .* flags WR \(no reference position\); home it$"):
            ax.position_deg()
    assert not ax.homed


def test_stop_and_clear_warnings(expected_protocol, clock, events):
    script = CONNECT + [(b"/1 1 stop:98\n", b"@01 1 OK IDLE FS 0\r\n"),
                        (b"/1 1 warnings clear:CE\n", b"@01 1 OK IDLE FS 01 FS\r\n")]
    with expected_protocol(script) as replay:
        ax = axis(replay.open_port, clock, events)
        ax.stop()                                        # a flag does not make stopping fail
        assert ax.clear_warnings() == ("FS",)


def test_info_alert_and_other_devices_lines_are_skipped(clock, events):
    script: list[Exchange] = [*CONNECT, (GET_POS, b"#01 1 some info\r\n!02 1 IDLE --\r\n@02 1 OK IDLE -- 7\r\n"
                                         b"@01 1 OK IDLE -- 42667:B3\r\n")]
    replay = Replay(script)
    ax = axis(lambda url, **port: LinePort(replay, port["timeout"]), clock, events)
    assert ax.position_deg() == pytest.approx(10.0, abs=1e-4)
    replay.check_complete()


@pytest.mark.parametrize("bad, problem", [
    (b"", r"arm: no complete reply to '/1 1 get pos:AC' within 0.2 s \(got b''\)"),
    (b"@01 1 OK IDLE -- 42667:00\r\n",
     r"arm_azimuth: reply to '/1 1 get pos:AC' fails its checksum: '@01 1 OK IDLE -- 42667:00'"),
    (b"@01 1 OK ID", r"arm: no complete reply to '/1 1 get pos:AC' within 0.2 s \(got b'@01 1 OK ID'\)"),
    (b"@01 1 OK IDLE -- 4x667\r\n", r"arm_azimuth: garbled reply to '/1 1 get pos:AC': '@01 1 OK IDLE -- 4x667'"),
    (b"\xc001 1 OK\r\n", r"arm: garbled reply to '/1 1 get pos:AC': b'\\xc001 1 OK\\r\\n'"),
], ids=["timeout", "checksum", "short", "data", "noise"])
def test_a_spoilt_reply_is_retried_after_a_reconnect(expected_protocol, clock, events, bad, problem):
    script = CONNECT + [(GET_POS, bad), (GET_POS, line("01 1 OK IDLE -- 42667"))]
    with expected_protocol(script) as replay:
        assert axis(replay.open_port, clock, events).position_deg() == pytest.approx(10.0, abs=1e-4)
    (retry, fields), (reconnect, _) = events
    assert (retry, reconnect, replay.opens) == ("retry", "reconnect", 2)
    assert fields["what"] == "/1 1 get pos:AC"
    assert re.fullmatch(problem, fields["error"])


def test_a_lasting_silence_is_a_persistent_unanswered_error(expected_protocol, clock, events):
    with expected_protocol(CONNECT + [(GET_POS, b"")] * 3) as replay:
        ax = axis(replay.open_port, clock, events)
        with pytest.raises(DeviceError, match=r"^arm_azimuth: /1 1 get pos:AC failed 3 times; last: ") as err:
            ax.position_deg()
    assert err.value.unanswered and not err.value.transient
    assert [k for k, _ in events] == ["retry", "reconnect"] * 2


def test_without_cycle_distance_the_configured_microstep_size_is_used(expected_protocol, clock, events):
    refused = (CONNECT[0][0], b"@01 1 RJ IDLE -- BADCOMMAND\r\n")
    with expected_protocol([refused, (CONNECT[1][0], b"@01 1 OK IDLE -- 2458\r\n"),
                            (CONNECT[2][0], b"@01 1 OK IDLE -- 2\r\n"), (b"/1 1 set accel 1:A9\n", IDLE),
                            (WARNINGS, NO_WARNINGS)]) as replay:
        ax = axis(replay.open_port, clock, events, microsteps_per_degree=100.0)
    assert ax.microsteps_per_degree == 100.0
    with expected_protocol([refused]) as replay:
        with pytest.raises(DeviceError, match="answers no limit.cycle.dist .*: configure microsteps_per_degree$"):
            axis(replay.open_port, clock, events)


def test_requests_without_checksum(expected_protocol, clock, events):
    with expected_protocol([(b"/1 1 get limit.cycle.dist\n", b"@01 1 OK IDLE -- 3600\r\n"),
                            (b"/1 1 get maxspeed\n", b"@01 1 OK IDLE -- 100\r\n"), (b"/1 1 set maxspeed 246\n", IDLE),
                            (b"/1 1 get accel\n", b"@01 1 OK IDLE -- 1\r\n"),
                            (b"/1 1 warnings\n", NO_WARNINGS)]) as replay:
        c = chain(replay.open_port, clock, events)
        c.checksum = False
        assert c.axis(1, 1, "a", 15.0, 30.0, 0.0).microsteps_per_degree == 10.0


def test_from_rig_addresses_two_devices_and_homes_the_unreferenced(expected_protocol, clock, events):
    second = [(b"/2 1 get limit.cycle.dist:BE\n", b"@02 1 OK IDLE -- 1536000\r\n"),
              (b"/2 1 get maxspeed:A6\n", b"@02 1 OK IDLE -- 104858\r\n"),
              (b"/2 1 get accel:05\n", b"@02 1 OK IDLE -- 30\r\n"),
              (b"/2 1 set accel 21:76\n", b"@02 1 OK IDLE -- 0\r\n"),
              (b"/2 1 warnings:F4\n", b"@02 1 OK IDLE -- 00\r\n")]
    homing = [(b"/1 1 home:B5\n", BUSY), (POLL, IDLE)]
    cfg = AxisConfig(limits_deg=(-180, 180), speed_deg_s=15, accel_deg_s2=30, settle_s=SETTLE)
    with expected_protocol(CONNECT_UNHOMED + second + homing) as replay:
        arm = ZaberChain.from_rig(clock=clock, settings={"arm_azimuth": cfg, "arm_polar": cfg}, name="arm",
                                  address="/dev/ttyUSB0", axes=[(1, 1), (2, 1)], home=True,
                                  open_port=replay.open_port)
    assert [a.homed for a in arm.axes] == [True, True]
    assert arm.identity() == "arm[Zaber device 1 axis 1 on /dev/ttyUSB0, Zaber device 2 axis 1 on /dev/ttyUSB0]"


def test_a_flag_latched_before_connecting_is_raised_by_the_first_move_and_can_be_cleared(expected_protocol, clock,
                                                                                         events):
    stalled = b"@01 1 OK IDLE FS 0\r\n"
    script = [(CONNECT[0][0], b"@01 1 OK IDLE FS 1536000\r\n"), (CONNECT[1][0], b"@01 1 OK IDLE FS 104858\r\n"),
              (CONNECT[2][0], b"@01 1 OK IDLE FS 21\r\n"),
              (WARNINGS, b"@01 1 OK IDLE FS 01 FS\r\n"), (GET_POS, stalled),
              (b"/1 1 warnings clear:CE\n", b"@01 1 OK IDLE FS 01 FS\r\n"), (GET_POS, IDLE), (MOVE_30, BUSY)]
    with expected_protocol(script) as replay:
        ax = axis(replay.open_port, clock, events)
        assert ax.homed
        with pytest.raises(DeviceError, match=r"get pos: .* flags FS \(stalled and stopped\)"):
            ax.start_move(30.0)
        ax.clear_warnings()
        ax.start_move(30.0)
