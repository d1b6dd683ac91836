"""Thorlabs FW102C filter-wheel driver: the exact byte exchanges, replayed in memory.

Provenance of the bytes (public sources): the command set and framing of the FW102C manual Rev H 2014
p. 11 (lower-case command + CR; echo + CR, reply + CR, prompt `> `); the exchanges `pos?\\r`→`pos?\\r3\\r> `,
`pos=5\\r`→`pos=5\\r> `, `pos=9\\r`→`pos=9\\rCommand error CMD_ARG_INVALID\\n\\r> ` and
`*idn?\\r`→`*idn?\\rTHORLABS FW102C/FW212C Filter Wheel version 1.04\\r> ` as github delmic/odemis
src/odemis/driver/tlfw.py records them (its simulator is also the source of the answer to a bare CR), and
odemis' move timing (1 s per position at high speed, twice that allowed). The captured `speed?` exchange is
replayed against the peer (tests/simulators/test_fw102c_peer.py): the driver sets the speed, never asks it.
"""

import pytest

from rig.core.errors import DeviceError
from rig.drivers.fw102c import FW102C
from rig.drivers.retry import RetryPolicy

IDENTITY = b"THORLABS FW102C/FW212C Filter Wheel version 1.04"
WAKE = (b"\r", b"\rCommand error CMD_NOT_DEFINED\n\r> ")
Script = list[tuple[bytes, bytes]]


def pos(n: int) -> tuple[bytes, bytes]:
    """`pos?` answered n."""
    return b"pos?\r", b"pos?\r%d\r> " % n


def move(n: int) -> tuple[bytes, bytes]:
    """`pos=n` acknowledged by its echo and the prompt once the wheel has stopped."""
    return b"pos=%d\r" % n, b"pos=%d\r> " % n


def connect_script(at: int = 3, count: int = 6, wake: tuple[bytes, bytes] = WAKE) -> Script:
    return [wake, (b"*idn?\r", b"*idn?\r" + IDENTITY + b"\r> "), (b"pcount?\r", b"pcount?\r%d\r> " % count),
            (b"speed=1\r", b"speed=1\r> "), (b"sensors=0\r", b"sensors=0\r> "), pos(at)]


CONNECT = connect_script()


def connect(open_port, clock, events, **options) -> FW102C:
    wheel = FW102C("/dev/ttyUSB0", clock=clock, timeout_s=0.2, open_port=open_port, **options)
    wheel.events = lambda kind, **fields: events.append((kind, fields))
    return wheel


def kinds(events) -> list[str]:
    return [kind for kind, _ in events]


# -- connect ---------------------------------------------------------------------------------------

def test_connect_wakes_identifies_and_sets_high_speed_and_sensors_off(expected_protocol, clock, events):
    with expected_protocol(CONNECT) as replay:
        wheel = connect(replay.open_port, clock, events)
        wheel.close()
    assert wheel.identity() == f"{IDENTITY.decode()} (6 positions)"
    assert wheel.positions == 6 and replay.opens == 1 and events == []


@pytest.mark.parametrize("answer", [b"", b"\x00\x00\r> ", b"\r> ", b"\x00\xff"],
                         ids=["silence", "stray NULs", "prompt", "noise"])
def test_whatever_answers_the_wake_up_cr_is_dropped(expected_protocol, clock, events, answer):
    with expected_protocol(connect_script(wake=(b"\r", answer))) as replay:
        connect(replay.open_port, clock, events).close()
    assert events == []


@pytest.mark.parametrize("identity", [b"THORLABS MFF101 version 1.0", b"FW102C", b""])
def test_another_instrument_is_refused_at_once(expected_protocol, clock, events, identity):
    with expected_protocol([WAKE, (b"*idn?\r", b"*idn?\r" + identity + b"\r> ")]) as replay:
        with pytest.raises(DeviceError, match=f"^attenuator: '\\*idn\\?' answered {identity.decode()!r}: not a "
                                              f"Thorlabs FW102C/FW212C filter wheel$") as err:
            connect(replay.open_port, clock, events)
    assert not err.value.transient and events == []


def test_a_refused_setting_at_connect_fails_the_connection(expected_protocol, clock, events):
    script = CONNECT[:4] + [(b"sensors=0\r", b"sensors=0\rCommand error CMD_NOT_DEFINED\n\r> ")]
    with expected_protocol(script) as replay:
        with pytest.raises(DeviceError, match="^attenuator: 'sensors=0' refused: Command error CMD_NOT_DEFINED$"):
            connect(replay.open_port, clock, events)
    assert events == []


# -- moves -----------------------------------------------------------------------------------------

def test_position_is_read_back(expected_protocol, clock, events):
    with expected_protocol(CONNECT + [pos(4)]) as replay:
        assert connect(replay.open_port, clock, events).position() == 4


@pytest.mark.parametrize("count, start, target, travel", [
    (6, 3, 5, 2), (6, 3, 4, 1), (6, 3, 6, 3), (6, 1, 6, 1), (6, 5, 2, 3), (12, 1, 7, 6), (12, 11, 2, 3)])
def test_a_move_waits_twice_its_time_the_shorter_way_round_then_confirms(expected_protocol, clock, events, count,
                                                                        start, target, travel):
    with expected_protocol(connect_script(start, count) + [move(target), pos(target)]) as replay:
        wheel = connect(replay.open_port, clock, events)
        wheel.move_to(target)
    assert replay.read_timeouts[-2] == pytest.approx(2 * (travel * 1.0 + 1.0))     # the prompt after `pos=`
    assert replay.read_timeouts[-1] == pytest.approx(0.2)                          # `pos?`: the link's own
    assert clock.now() == 0.0 and events == []          # the wheel takes the time before its prompt


def test_moving_to_where_the_wheel_is_sends_nothing(expected_protocol, clock, events):
    with expected_protocol(CONNECT + [move(5), pos(5)]) as replay:
        wheel = connect(replay.open_port, clock, events)
        wheel.move_to(3)
        wheel.move_to(5)
        wheel.move_to(5)


@pytest.mark.parametrize("position", [0, 7, -1])
def test_a_position_the_wheel_lacks_is_refused_before_sending(expected_protocol, clock, events, position):
    with expected_protocol(CONNECT) as replay:
        wheel = connect(replay.open_port, clock, events)
        with pytest.raises(DeviceError, match=f"^attenuator: no filter position {position}: the wheel has "
                                              f"positions 1 … 6$") as err:
            wheel.move_to(position)
    assert not err.value.transient


def test_the_wheels_command_error_is_persistent_and_named(expected_protocol, clock, events):
    """The captured `pos=9` refusal (here from a wheel that said it had 12 positions)."""
    refusal = (b"pos=9\r", b"pos=9\rCommand error CMD_ARG_INVALID\n\r> ")
    with expected_protocol(connect_script(count=12) + [refusal]) as replay:
        wheel = connect(replay.open_port, clock, events)
        with pytest.raises(DeviceError, match="^attenuator: 'pos=9' refused: Command error CMD_ARG_INVALID$") as err:
            wheel.move_to(9)
    assert not err.value.transient and events == []


def test_a_wheel_that_did_not_get_there_is_a_persistent_error(expected_protocol, clock, events):
    """Jammed: the prompt comes, `pos?` tells the old position; not retried. The next move is sent again."""
    with expected_protocol(CONNECT + [move(5), pos(3), move(5), pos(5)]) as replay:
        wheel = connect(replay.open_port, clock, events)
        with pytest.raises(DeviceError, match=r"^attenuator: 'pos=5' ended at position 3, not 5 "
                                              r"\(is the wheel jammed or held\?\)$") as err:
            wheel.move_to(5)
        wheel.move_to(3)                      # known to be there: nothing sent
        wheel.move_to(5)
    assert not err.value.transient and events == []


# -- transient faults: retried after a reconnect ---------------------------------------------------

@pytest.mark.parametrize("reply", [b"pos?\r\xb3\r> ", b"pcount?\r6\r> ", b"pos?\r3", b"", b"pos?\rx\r> ",
                                   b"pos?\r7\r> ", b"pos?\r\r> "],
                         ids=["garbled", "wrong echo", "no prompt", "silence", "not a number", "no such position",
                              "empty"])
def test_a_spoilt_reply_is_retried_after_a_reconnect(expected_protocol, clock, events, reply):
    with expected_protocol(CONNECT + [(b"pos?\r", reply)] + CONNECT + [pos(2)]) as replay:
        wheel = connect(replay.open_port, clock, events)
        assert wheel.position() == 2
    assert kinds(events) == ["retry", "reconnect"] and replay.opens == 2


def test_a_lost_prompt_after_a_move_that_happened_is_not_moved_again(expected_protocol, clock, events):
    """The reconnect's `pos?` finds the wheel at the target: the retry has nothing left to do."""
    with expected_protocol(CONNECT + [(b"pos=5\r", b"pos=5\r")] + connect_script(at=5)) as replay:
        wheel = connect(replay.open_port, clock, events)
        wheel.move_to(5)
    assert kinds(events) == ["retry", "reconnect"]
    assert "no complete reply to 'pos=5' within 6 s" in events[0][1]["error"]


def test_a_move_lost_on_the_way_is_sent_again(expected_protocol, clock, events):
    with expected_protocol(CONNECT + [(b"pos=5\r", b"")] + CONNECT + [move(5), pos(5)]) as replay:
        wheel = connect(replay.open_port, clock, events)
        wheel.move_to(5)
    assert kinds(events) == ["retry", "reconnect"]
    assert replay.read_timeouts[-2] == pytest.approx(6.0)


def test_a_wheel_that_stops_answering_is_unanswered_after_the_retries(expected_protocol, clock, events):
    lost = (b"pos?\r", b"")
    with expected_protocol(CONNECT + [lost, WAKE, (b"*idn?\r", b""), lost]) as replay:
        wheel = connect(replay.open_port, clock, events, retry=RetryPolicy(attempts=2, backoff_s=0.5))
        with pytest.raises(DeviceError, match=r"^attenuator: pos\? failed 2 times; last: attenuator: no complete "
                                              r"reply to 'pos\?' within 0.2 s") as err:
            wheel.position()
    assert err.value.unanswered
    assert kinds(events) == ["retry", "reconnect_failed"] and clock.now() == pytest.approx(0.5)


def test_after_a_failed_move_the_next_allows_for_half_the_wheel(expected_protocol, clock, events):
    """The position is unknown until read back: the next `pos=` is sent even to the old target."""
    with expected_protocol(CONNECT + [(b"pos=4\r", b"")] + [move(4), pos(4)]) as replay:
        wheel = connect(replay.open_port, clock, events, retry=RetryPolicy(attempts=1))
        with pytest.raises(DeviceError, match="no complete reply to 'pos=4' within 4 s"):
            wheel.move_to(4)
        wheel.move_to(4)
    assert replay.read_timeouts[-2] == pytest.approx(2 * (3 + 1.0))
