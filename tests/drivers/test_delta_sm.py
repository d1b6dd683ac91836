"""Delta SM15K lamp-supply driver: the exact byte exchanges, replayed in memory.

Replies follow the examples of the manual "Ethernet & Sequencer Programming SM15K", rev. July 2021
(§5.1.1 `*IDN?`, §5.2.2 maxima as integers, §5.2.7 `14.0000`, §5.6.7 `0,None`, §5.6.10 watchdog `823`,
`0`, `-1`), via github keklikyusuf/DeltaElektronika. The driver against the protocol peer over loopback
TCP is in test_delta_sm_integration.py.
"""

from collections.abc import Iterator
from contextlib import contextmanager

import pytest
from shared import DELTA_SM_CLOSE as CLOSE
from shared import DELTA_SM_CONNECT as CONNECT
from shared import DELTA_SM_IDN as IDN
from shared import DELTA_SM_OK as OK

from rig.core.errors import DeviceError
from rig.drivers.delta_sm import DeltaSM, plain
from rig.drivers.retry import RetryPolicy

OPTIONS = dict(current_a=4.17, current_limit_a=4.6, watchdog_s=1.0, ramp_s=0.0, voltage_limit_v=14.0)


def wire(exchanges: list[tuple[str, str | None]]) -> list[tuple[bytes, bytes | None]]:
    """SCPI lines as they go on the wire: ASCII, LF-terminated both ways; settings get no reply."""
    return [(line.encode("ascii") + b"\n", None if reply is None else reply.encode("ascii") + b"\n")
            for line, reply in exchanges]


def lines(exchanges: list[tuple]) -> list[bytes]:
    return [line for line, _ in exchanges]


@pytest.fixture
def scripted(expected_protocol, clock, events):
    """`with scripted(exchanges, **driver options) as (lamp, replay)`: a driver connected over a replay
    of `connect`, `exchanges`, `close` (the test closes the driver)."""
    @contextmanager
    def start(exchanges: list[tuple[str, str | None]], connect=CONNECT, close=CLOSE, **kw) -> Iterator[tuple]:
        script = wire(connect + exchanges + close)
        with expected_protocol(script, now=clock.now) as replay:
            lamp = DeltaSM("socket://lamp:8462", clock=clock, timeout_s=0.2, open_port=replay.open_port,
                           **(OPTIONS | kw))
            lamp.events = lambda kind, **fields: events.append((kind, fields))
            yield lamp, replay
        assert lines(replay.written) == lines(script)
    return start


def test_connect_arms_the_watchdog_output_measurements_and_close_disarms(scripted, clock):
    with scripted([("SOURce:CURrent 4.1700", None), OK,
                   ("OUTPut ON", None), OK,
                   ("OUTPut?", "1"),
                   ("MEASure:VOLtage?", "11.9987"), ("MEASure:CURrent?", "4.1700")]) as (lamp, _):
        assert lamp.identity() == IDN
        assert lamp.max_current_a == 90.0
        lamp.set_current(4.17)                 # no ramp: one step, no read of the present setpoint
        lamp.set_output(True)
        assert lamp.output_is_on() is True
        assert lamp.measure_voltage_v() == pytest.approx(11.9987, abs=1e-9)
        assert lamp.measure_current_a() == pytest.approx(4.17, abs=1e-9)
        lamp.close()                           # disarm, then both setpoints back to the front panel
    assert clock.now() == 0.0


def test_without_a_voltage_limit_nothing_is_opened_and_the_key_is_named(expected_protocol, clock):
    with expected_protocol([]) as replay:
        with pytest.raises(DeviceError, match=r"lamp: no lamp voltage limit: set lamp.voltage_limit_v in the rig file"):
            DeltaSM("socket://lamp:8462", clock=clock, open_port=replay.open_port,
                    **(OPTIONS | dict(voltage_limit_v=None)))
    assert replay.opens == 0


def test_a_voltage_limit_above_the_supply_maximum_fails_before_any_setting(expected_protocol, clock):
    with expected_protocol(wire(CONNECT[:4])) as replay:
        with pytest.raises(DeviceError, match=r"lamp: voltage limit 600 V exceeds the supply's maximum 500 V"):
            DeltaSM("socket://lamp:8462", clock=clock, open_port=replay.open_port,
                    **(OPTIONS | dict(voltage_limit_v=600.0)))


def test_a_voltage_limit_that_reads_back_differently_fails_the_connection(expected_protocol, clock):
    script = wire(CONNECT[:15] + [("SYSTem:LIMits:VOLtage?", "500.0000")])
    with expected_protocol(script) as replay:
        with pytest.raises(DeviceError, match=r"voltage limit reads back as 500 V after setting 14 V"):
            DeltaSM("socket://lamp:8462", clock=clock, open_port=replay.open_port, **OPTIONS)


@pytest.mark.parametrize("value, text", [(4.17, "4.1700"), (1e-5, "0.0000"), (0.00005, "0.0001"),
                                         (2.0, "2.0000"), (-1e-17, "0.0000"), (12.34567, "12.3457")])
def test_numbers_go_out_as_plain_decimals(value, text):
    assert plain(value) == text


def test_a_tiny_current_is_sent_without_exponent(scripted):
    with scripted([("SOURce:CURrent 0.0000", None), OK]) as (lamp, _):
        lamp.set_current(1e-5)
        lamp.close()


def test_an_expired_watchdog_found_on_connect_is_reported_to_the_first_sink(scripted, events):
    connect = [CONNECT[0], ("SYSTem:COMmunicate:WATchdog?", "0"), *CONNECT[2:]]
    with scripted([], connect=connect) as (lamp, _):
        lamp.close()
    assert [kind for kind, _ in events] == ["watchdog_expired_before_connect"]


def test_the_keep_alive_feeds_the_watchdog_during_a_long_sleep(scripted, clock):
    feeds = [("SYSTem:COMmunicate:WATchdog?", ms) for ms in ("750", "750", "750", "750", "751", "750")]
    with scripted(feeds) as (lamp, replay):
        clock.sleep(1.5)                       # 1.5 × the watchdog: a feed every quarter of it
        lamp.close()
        clock.sleep(5.0)                       # closed: no more feeds
    times = [t for line, t in replay.written if line == b"SYSTem:COMmunicate:WATchdog?\n"][1:]
    assert times == pytest.approx([0.25, 0.5, 0.75, 1.0, 1.25, 1.5])


def test_a_feed_right_after_a_reply_is_skipped_but_never_two_in_a_row(scripted, clock):
    measure, feed = ("MEASure:CURrent?", "4.1700"), ("SYSTem:COMmunicate:WATchdog?", "750")
    with scripted([measure, feed, measure, measure, feed]) as (lamp, replay):
        clock.sleep(0.2)
        lamp.measure_current_a()               # at 0.2 s: restarts the watchdog, so the feed due at 0.25 s is
        clock.sleep(0.3)                       # skipped; the one at 0.5 s is sent
        clock.sleep(0.1)
        lamp.measure_current_a()               # at 0.6 s: the feed at 0.75 s is skipped ...
        clock.sleep(0.2)
        lamp.measure_current_a()               # ... and the one at 1.0 s, 0.2 s after this reply, is not
        clock.sleep(0.2)
        lamp.close()
    times = [t for line, t in replay.written if line == b"SYSTem:COMmunicate:WATchdog?\n"][1:]
    assert times == pytest.approx([0.5, 1.0])


def test_an_expired_watchdog_is_reported_and_re_armed_by_the_feed(scripted, clock, events):
    with scripted([("SYSTem:COMmunicate:WATchdog?", "0"),
                   ("SYSTem:COMmunicate:WATchdog SET,1000", None), OK]) as (lamp, _):
        clock.sleep(0.25)
        lamp.close()
    assert [kind for kind, _ in events] == ["watchdog_expired"]


def test_a_watchdog_found_off_with_the_lamp_on_reapplies_the_settings_and_the_lamp_may_be_switched_on(scripted,
                                                                                                        clock, events):
    """-1 where rig armed it: the time-out was read elsewhere (a reply lost in a stall) or the supply restarted
    (setpoints at 0): the session's settings again, and the output may be switched on again."""
    on = [("OUTPut ON", None), OK]
    found_off = [("SYSTem:COMmunicate:WATchdog?", "-1"), *CONNECT[4:]]
    loss = [("STATus:REGister:A?", "0"), ("OUTPut?", "0"), ("SYSTem:COMmunicate:WATchdog?", "1000")]
    with scripted(on + found_off + loss) as (lamp, _):
        lamp.set_output(True)
        clock.sleep(0.25)
        assert lamp.output_loss().restart
        lamp.close()
    assert [kind for kind, _ in events] == ["watchdog_off"]


def test_a_failed_feed_is_reported_once_and_swallowed(scripted, clock, events):
    with scripted([("SYSTem:COMmunicate:WATchdog?", "")]) as (lamp, replay):
        replay.exchanges[len(CONNECT)] = (b"SYSTem:COMmunicate:WATchdog?\n", b"")     # no reply: a timeout
        clock.sleep(0.25)
        lamp.close()
    assert [kind for kind, _ in events] == ["watchdog_feed_failed"]
    assert "no complete reply to 'SYSTem:COMmunicate:WATchdog?'" in events[0][1]["error"]


def test_switching_off_ramps_down_then_off_then_verifies(scripted, clock):
    ramp = [("OUTPut?", "1"), ("SOURce:CURrent?", "4.1700")]
    for value in ("3.1275", "2.0850", "1.0425", "0.0000"):
        ramp += [(f"SOURce:CURrent {value}", None), OK]
    # no feed at 0.25 s: the supply answered the error query after the step at 0.2 s (that restarted the watchdog)
    off = [("OUTPut OFF", None), OK, ("OUTPut?", "0"), ("MEASure:CURrent?", "0.0000")]
    with scripted(ramp + off, ramp_s=0.4) as (lamp, replay):
        lamp.set_output(False)
        lamp.close()
    assert [t for line, t in replay.written if line.startswith(b"SOURce:CURrent ")] == \
        pytest.approx([0.1, 0.2, 0.3, 0.4])


def test_the_switch_off_ramp_is_at_most_two_seconds_and_skipped_when_off(scripted, clock):
    off = [("OUTPut OFF", None), OK, ("OUTPut?", "0"), ("MEASure:CURrent?", "0.0000")]
    with scripted([("OUTPut?", "0")] + off, ramp_s=300.0) as (lamp, _):
        lamp.set_output(False)
        lamp.close()
    with scripted([("OUTPut?", "1"), ("SOURce:CURrent?", "0.0000")] + off, ramp_s=300.0) as (lamp, _):
        lamp.set_output(False)
        lamp.close()
    assert clock.now() == 0.0


def test_a_failing_ramp_does_not_prevent_output_off(scripted, events):
    off = [("OUTPut OFF", None), OK, ("OUTPut?", "0"), ("MEASure:CURrent?", "0.0000")]
    with scripted([("OUTPut?", "1"), ("SOURce:CURrent?", "4.1700"),
                   ("SOURce:CURrent 2.0850", None), ("SYSTem:ERRor?", "-221,Settings conflict"), OK,
                   ("SOURce:CURrent 0.0000", None), ("SYSTem:ERRor?", "")] + off,
                  ramp_s=0.2, retry=RetryPolicy(attempts=3, backoff_s=0.0)) as (lamp, _):
        lamp.set_output(False)                 # an entry is reported, a garbled reply ends the ramp at once
        lamp.close()
    assert [kind for kind, _ in events] == ["device_errors", "switch_off_ramp_failed"]
    assert events[0][1] == {"device": "lamp", "what": "SOURce:CURrent 2.0850", "errors": ["-221,Settings conflict"]}
    assert events[1][1]["error"].startswith("lamp: SOURce:CURrent 0.0000 failed 1 times")


def test_current_still_flowing_after_off_is_retried_then_a_device_error(scripted, events):
    still = [("OUTPut OFF", None), OK, ("OUTPut?", "0"), ("MEASure:CURrent?", "0.5000")]
    with scripted(still * 6, retry=RetryPolicy(attempts=2, backoff_s=0.0)) as (lamp, replay):
        with pytest.raises(DeviceError) as err:
            lamp.set_output(False)
        lamp.close()
    assert str(err.value).startswith("lamp: OUTPut OFF failed 6 times; last: lamp: output still carries 0.5 A "
                                     "after 'OUTPut OFF' (off means below 0.046 A)")
    assert [kind for kind, _ in events].count("retry") == 5 and replay.opens == 6


def test_verify_that_fails_once_is_retried(scripted, events):
    with scripted([("OUTPut OFF", None), OK, ("OUTPut?", "1"),
                   ("OUTPut OFF", None), OK, ("OUTPut?", "0"), ("MEASure:CURrent?", "0.0020")]) as (lamp, _):
        lamp.set_output(False)
        lamp.close()
    assert [kind for kind, _ in events] == ["retry", "reconnect"]
    assert events[0][1]["error"] == "lamp: output still on after 'OUTPut OFF'"


@pytest.mark.parametrize("current_a, message", [(4.7, r"current 4.7 A outside 0 … 4.6 A \(the current limit\)"),
                                                (-0.1, r"current -0.1 A outside 0 … 4.6 A")])
def test_setpoints_outside_the_limit_are_refused_before_anything_is_sent(scripted, clock, current_a, message):
    with scripted([]) as (lamp, _):
        with pytest.raises(DeviceError, match=message):
            lamp.set_current(current_a, ramp_s=5.0)
        lamp.close()
    assert clock.now() == 0.0


def test_a_limit_above_the_supply_maximum_fails_the_connection(expected_protocol, clock):
    with expected_protocol(wire(CONNECT[:4])) as replay:
        with pytest.raises(DeviceError, match=r"lamp: current limit 95 A exceeds the supply's maximum 90 A"):
            DeltaSM("socket://lamp:8462", clock=clock, open_port=replay.open_port,
                    **(OPTIONS | dict(current_a=4.17, current_limit_a=95.0)))


def test_a_lamp_current_above_the_limit_fails_before_opening(expected_protocol, clock):
    with expected_protocol([]) as replay:
        with pytest.raises(DeviceError, match=r"lamp current 5 A exceeds the current limit 4.6 A"):
            DeltaSM("socket://lamp:8462", clock=clock, open_port=replay.open_port, **(OPTIONS | dict(current_a=5.0)))
    assert replay.opens == 0


def test_a_limit_that_reads_back_differently_fails_the_connection(expected_protocol, clock):
    script = wire(CONNECT[:12] + [("SYSTem:LIMits:CURrent?", "90.0000")])
    with expected_protocol(script) as replay:
        with pytest.raises(DeviceError, match=r"current limit reads back as 90 A after setting 4.6 A"):
            DeltaSM("socket://lamp:8462", clock=clock, open_port=replay.open_port, **OPTIONS)


def test_another_instrument_is_refused(expected_protocol, clock):
    with expected_protocol(wire([("*IDN?", "KEYSIGHT,E36312A,MY1,1.0")])) as replay:
        with pytest.raises(DeviceError, match=r"lamp: not a Delta Elektronika supply: '\*IDN\?' answered"):
            DeltaSM("socket://lamp:8462", clock=clock, open_port=replay.open_port, **OPTIONS)


@pytest.mark.parametrize("watchdog_s", [0.01, 10.5])
def test_a_watchdog_outside_the_supply_range_is_a_value_error(watchdog_s, clock):
    with pytest.raises(ValueError, match="watchdog_s must be 0.02 … 10 s"):
        DeltaSM("socket://lamp:8462", clock=clock, **(OPTIONS | dict(watchdog_s=watchdog_s)))


def test_current_is_ramped_in_steps_on_the_clock_with_an_error_read_after_each(scripted):
    steps = [("SOURce:CURrent?", "1.0000")]        # the ramp starts from the supply's present setpoint
    for value in ("1.5000", "2.0000", "2.5000", "3.0000"):
        steps += [(f"SOURce:CURrent {value}", None), OK]
    # the keep-alive due at 0.25 s is skipped: the error query after the step at 0.2 s restarted the watchdog
    with scripted(steps, ramp_step_s=0.1) as (lamp, replay):
        lamp.set_current(3.0, ramp_s=0.4)
        lamp.close()
    assert [t for line, t in replay.written if line.startswith(b"SOURce:CURrent ")] == \
        pytest.approx([0.1, 0.2, 0.3, 0.4])


def test_a_refused_setting_drains_the_queue_and_names_command_and_entries(scripted):
    with scripted([("SOURce:CURrent 4.1700", None), ("SYSTem:ERRor?", "-221,Settings conflict"),
                   ("SYSTem:ERRor?", "-300,Device-specific error"), OK]) as (lamp, _):
        with pytest.raises(DeviceError) as err:
            lamp.set_current(4.17)
        assert not err.value.transient
        assert str(err.value) == ("lamp: 'SOURce:CURrent 4.1700' refused: -221,Settings conflict; "
                                  "-300,Device-specific error")
        lamp.close()


def test_close_tries_every_step_once_and_raises_the_first_failure(scripted, clock):
    close = [("SYSTem:COMmunicate:WATchdog STOP", None), ("SYSTem:ERRor?", "-113,Undefined header"), OK,
             ("SYSTem:REMote:CV LOCal", None), OK, ("SYSTem:REMote:CC LOCal", None), OK]
    with scripted([], close=close) as (lamp, replay):
        with pytest.raises(DeviceError, match="'SYSTem:COMmunicate:WATchdog STOP' refused: -113,Undefined header"):
            lamp.close()
        clock.sleep(5.0)                       # the keep-alive was cancelled all the same
    assert replay.opens == 1


def test_a_garbled_reply_is_retried_after_a_reconnect_with_the_same_request(expected_protocol, clock, events):
    garbled = bytes(b | 0x80 for b in b"4.1700") + b"\n"
    script = (wire(CONNECT) + [(b"MEASure:CURrent?\n", garbled), (b"MEASure:CURrent?\n", b"4.1700\n")]
              + wire(CLOSE))
    with expected_protocol(script) as replay:
        lamp = DeltaSM("socket://lamp:8462", clock=clock, timeout_s=0.2, open_port=replay.open_port, **OPTIONS)
        lamp.events = lambda kind, **fields: events.append((kind, fields))
        assert lamp.measure_current_a() == pytest.approx(4.17, abs=1e-9)
        lamp.close()
    assert [kind for kind, _ in events] == ["retry", "reconnect"]
    assert events[0][1]["error"] == f"lamp: garbled reply to 'MEASure:CURrent?': {garbled!r}"
    assert replay.opens == 2
