"""Delta SM lamp-supply driver: the exact byte exchanges, replayed in memory.

The driver against the protocol peer over loopback TCP, and every fault, is in
test_delta_sm_integration.py.
"""

from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from rig.core.errors import DeviceError
from rig.drivers.delta_sm import DeltaSM
from rig.simulators.clock import SimClock

CONNECT = [("*IDN?", "DELTA ELEKTRONIKA BV,SM15-100,1234,P0198"),
           ("*CLS", None), ("SYSTem:ERRor?", "0,None"),
           ("SYSTem:REMote:CV REMote", None), ("SYSTem:ERRor?", "0,None"),
           ("SYSTem:REMote:CC REMote", None), ("SYSTem:ERRor?", "0,None"),
           ("SOURce:CURrent:MAXimum?", "100.0000"),
           ("SOURce:VOLtage:MAXimum?", "15.3000"),
           ("SOURce:VOLtage 15.3", None), ("SYSTem:ERRor?", "0,None")]
CLOSE = [("SYSTem:REMote:CV LOCal", None), ("SYSTem:ERRor?", "0,None"),
         ("SYSTem:REMote:CC LOCal", None), ("SYSTem:ERRor?", "0,None")]


def wire(exchanges: list[tuple[str, str | None]]) -> list[tuple[bytes, bytes | None]]:
    """SCPI lines as they go on the wire: ASCII, LF-terminated both ways; settings get no reply."""
    return [(line.encode("ascii") + b"\n", None if reply is None else reply.encode("ascii") + b"\n")
            for line, reply in exchanges]


def lines(exchanges: list[tuple]) -> list[bytes]:
    return [line for line, _ in exchanges]


@pytest.fixture
def clock() -> SimClock:
    return SimClock()


@pytest.fixture
def scripted(expected_protocol, clock):
    """`with scripted(exchanges, **driver options) as (lamp, replay)`: a driver connected over a replay
    of connect, `exchanges`, close (the test closes the driver)."""
    @contextmanager
    def start(exchanges: list[tuple[str, str | None]], **kw) -> Iterator[tuple]:
        script = wire(CONNECT + exchanges + CLOSE)
        with expected_protocol(script, now=clock.now) as replay:
            yield DeltaSM("socket://lamp:8462", clock=clock, timeout_s=0.2, open_port=replay.open_port, **kw), replay
        assert lines(replay.written) == lines(script)
    return start


def test_connect_output_measurements_and_close(scripted, clock):
    with scripted([("SOURce:CURrent 4.17", None), ("SYSTem:ERRor?", "0,None"),
                   ("OUTPut ON", None), ("SYSTem:ERRor?", "0,None"),
                   ("OUTPut?", "1"),
                   ("MEASure:VOLtage?", "11.9987"), ("MEASure:CURrent?", "4.1700"),
                   ("OUTPut OFF", None), ("SYSTem:ERRor?", "0,None"), ("OUTPut?", "0")]) as (lamp, _):
        assert lamp.identity() == "DELTA ELEKTRONIKA BV,SM15-100,1234,P0198"
        lamp.set_current(4.17)                 # no ramp: one step, no read of the present setpoint
        lamp.set_output(True)
        assert lamp.output_is_on() is True
        assert lamp.measure_voltage_v() == 11.9987
        assert lamp.measure_current_a() == 4.17
        lamp.set_output(False)
        lamp.close()                           # hands both setpoints back to the front panel
    assert clock.now() == 0.0


def test_configured_compliance_replaces_the_maximum(expected_protocol, clock):
    script = wire(CONNECT[:8] + [("SOURce:VOLtage 13.5", None), ("SYSTem:ERRor?", "0,None")] + CLOSE)
    with expected_protocol(script) as replay:
        DeltaSM("socket://lamp:8462", clock=clock, timeout_s=0.2, compliance_v=13.5,
                open_port=replay.open_port).close()
    assert lines(replay.written) == lines(script)


def test_current_is_ramped_in_steps_on_the_clock_with_an_error_read_after_each(scripted):
    steps = [("SOURce:CURrent?", "1.0000")]        # the ramp starts from the supply's present setpoint
    for value in ("1.5", "2", "2.5", "3"):
        steps += [(f"SOURce:CURrent {value}", None), ("SYSTem:ERRor?", "0,None")]
    with scripted(steps, ramp_step_s=0.1) as (lamp, replay):
        lamp.set_current(3.0, ramp_s=0.4)
        lamp.close()
    assert [t for line, t in replay.written if line.startswith(b"SOURce:CURrent ")] == \
        pytest.approx([0.1, 0.2, 0.3, 0.4])


def test_a_refused_setting_drains_the_queue_and_names_command_and_entries(scripted):
    with scripted([("SOURce:CURrent 4.17", None), ("SYSTem:ERRor?", "-221,Settings conflict"),
                   ("SYSTem:ERRor?", "-300,Device-specific error"), ("SYSTem:ERRor?", "0,None")]) as (lamp, _):
        with pytest.raises(DeviceError) as err:
            lamp.set_current(4.17)
        assert not err.value.transient
        assert str(err.value) == ("lamp: 'SOURce:CURrent 4.17' refused: -221,Settings conflict; "
                                  "-300,Device-specific error")
        lamp.close()


def test_a_garbled_reply_is_retried_after_a_reconnect_with_the_same_request(expected_protocol, clock):
    garbled = bytes(b | 0x80 for b in b"4.1700") + b"\n"
    script = (wire(CONNECT) + [(b"MEASure:CURrent?\n", garbled), (b"MEASure:CURrent?\n", b"4.1700\n")]
              + wire(CLOSE))
    events = []
    with expected_protocol(script) as replay:
        lamp = DeltaSM("socket://lamp:8462", clock=clock, timeout_s=0.2, open_port=replay.open_port)
        lamp.events = lambda kind, **fields: events.append((kind, fields))
        assert lamp.measure_current_a() == 4.17
        lamp.close()
    assert [kind for kind, _ in events] == ["retry", "reconnect"]
    assert events[0][1]["error"] == f"lamp: garbled reply to 'MEASure:CURrent?': {garbled!r}"
    assert replay.opens == 2
