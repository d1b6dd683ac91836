"""P-9710 optometer driver: the exact byte exchanges, replayed in memory; the rebuilt peer passes the same.

Provenance of the bytes (public sources):
- the manual: P-9710 Operating Manual V1.20, §15 Remote Interface (error replies `?x`, the bare LF that
  acknowledges a command without answer, `SN` p × 0.1 ms, `MA`/`GR` answers, chained commands), via
  github matusm/Bev.Instruments.P9710.Detector doc/GO_P-9710_RemoteInterface.pdf;
- a real firmware 5.6 unit: `GI`→`P9710 V5.6`, `TF`→`521`, `TT`→`1875`, `GK`→`VL__` (github
  matusm/Bev.Instruments.P9710 P9710.cs builds "P9710-521 V5.6 SN:1875" from them, as logged in
  matusm/Bev.Instruments.P9710.Detector doc/BruteForce.txt), LF framing from P9710.cs.

The same exchanges replayed against the rebuilt peer over its pty, the peer's answers to every command
and error, and the driver against the peer with every fault, are in test_p9710_integration.py.
"""

import pytest
from shared import P9710_CONNECT as CONNECT
from shared import P9710_READING as READING
from shared import P9710_TD0 as TD0

from rig.core.errors import DeviceError
from rig.drivers.p9710 import ERROR_BITS, P9710, RANGE_FLOOR_A, UNDERLOAD, error_meaning

CAL = 1.0e9
#: The manual's identity form (§15.3.9: `GI` answers `P-9710 x.x`).
CONNECT_MANUAL = [TD0, (b"GI\n", b"P-9710 4.7\n")] + CONNECT[2:]


def connect(open_port, clock, events, **options) -> P9710:
    meter = P9710("/dev/ttyUSB0", calibration_lx_per_a=CAL, clock=clock, timeout_s=0.2, open_port=open_port,
                  **options)
    meter.events = lambda kind, **fields: events.append((kind, fields))
    return meter


def requests(script):
    return [request for request, *_ in script]


@pytest.mark.parametrize("script, model", [(CONNECT, "P9710 V5.6"), (CONNECT_MANUAL, "P-9710 4.7")],
                         ids=["real unit", "manual"])
def test_connect_and_one_reading_with_its_range(expected_protocol, clock, events, script, model):
    with expected_protocol(script + [READING]) as replay:
        meter = connect(replay.open_port, clock, events)
        t0 = clock.now()
        reading = meter.read()
        meter.close()
    assert meter.identity() == f"Gigahertz-Optik {model} SN 1875 detector VL__"
    assert reading.photocurrent_a == 1.2345e-6
    assert reading.illuminance_lx == pytest.approx(1.2345e-6 * CAL)
    assert reading.calibration_lx_per_a == CAL and reading.range_index == 3
    assert clock.now() == t0          # the meter integrates before it answers: the driver does not sleep
    assert events == [] and replay.opens == 1


def test_measuring_range_alone(expected_protocol, clock, events):
    with expected_protocol(CONNECT + [(b"GR\n", b"7\n")]) as replay:
        meter = connect(replay.open_port, clock, events)
        assert meter.measuring_range() == 7


@pytest.mark.parametrize("identity", [b"K8000 V1.0", b"P9711 V5.6", b"P9710", b""])
def test_another_instrument_is_refused_at_once(expected_protocol, clock, events, identity):
    with expected_protocol([TD0, (b"GI\n", identity + b"\n")]) as replay:
        with pytest.raises(DeviceError, match=f"^meter: 'GI' answered {identity.decode()!r}: not a P-9710$") as err:
            connect(replay.open_port, clock, events)
    assert not err.value.transient and events == []


@pytest.mark.parametrize("integration_s, command", [(1e-4, b"SN1\n"), (0.2, b"SN2000\n"), (5.9999, b"SN59999\n")])
def test_integration_time_is_set_in_tenths_of_a_millisecond(expected_protocol, clock, events, integration_s,
                                                            command):
    with expected_protocol(CONNECT[:5] + [(command, b"\n")]) as replay:
        connect(replay.open_port, clock, events, integration_s=integration_s)


@pytest.mark.parametrize("integration_s", [0.0, 4e-5, 6.0])
def test_an_integration_time_the_meter_cannot_set_is_refused_before_connecting(expected_protocol, clock, events,
                                                                               integration_s):
    with expected_protocol([]) as replay:
        with pytest.raises(ValueError, match="outside the P-9710's 0.1 ms … 5.9999 s"):
            connect(replay.open_port, clock, events, integration_s=integration_s)
    assert replay.opens == 0


def test_reading_timeout_is_integration_plus_autorange_plus_link(expected_protocol, clock, events):
    """The port is opened with the link's timeout; a reading's reply alone may take the measurement longer."""
    seen = []
    with expected_protocol(CONNECT[:5] + [(b"SN2500\n", b"\n"), READING, (b"GR\n", b"3\n")]) as replay:
        def open_port(url, *, baudrate, timeout, write_timeout):
            seen.append(("open", baudrate, timeout))
            port = replay.open_port(url, baudrate=baudrate, timeout=timeout, write_timeout=write_timeout)
            port.timeout = timeout
            read = port.read_until

            def read_until(*args):
                seen.append(("read", port.timeout))
                return read(*args)
            port.read_until = read_until
            return port
        meter = connect(open_port, clock, events, integration_s=0.25, autorange_s=0.1)
        meter.read()
        meter.measuring_range()
    assert seen[0] == ("open", 9600, 0.2)
    reads = [timeout for kind, timeout, *_ in seen if kind == "read"]
    assert reads[:6] == [0.2] * 6 and reads[7] == 0.2
    assert reads[6] == pytest.approx(0.25 + 0.1 + 0.2)


# -- error replies: the meter's verdict, never retried -----------------------------------------------

@pytest.mark.parametrize("code, meaning", [(code, error_meaning(code)) for code in (*ERROR_BITS, 48)
                                           if code != UNDERLOAD])
def test_each_error_code_on_a_reading_is_a_persistent_error_naming_it(expected_protocol, clock, events,
                                                                      code, meaning):
    """Every code but a lone underload (below): overload and underload together (48) are an error too."""
    with expected_protocol(CONNECT + [(b"MA;GR\n", f"?{code}\n".encode())]) as replay:
        meter = connect(replay.open_port, clock, events)
        with pytest.raises(DeviceError) as err:
            meter.read()
    assert str(err.value) == f"meter: 'MA;GR' answered '?{code}': {meaning}"
    assert not err.value.transient and not err.value.unanswered
    assert events == [] and replay.opens == 1


def test_overload_and_underload_say_what_the_light_is_like():
    assert error_meaning(16).startswith("input signal overload") and "2 mA" in error_meaning(16)
    assert error_meaning(32).startswith("input signal underload") and "no light" in error_meaning(32)


@pytest.mark.parametrize("code, meaning", [
    (3, "command not allowed + command parameter not allowed"),
    (48, f"{ERROR_BITS[16]} + {ERROR_BITS[32]}"),
    (130, "command parameter not allowed + undocumented error bits 128"),
    (0, "undocumented error bits 0"),
])
def test_a_combined_code_names_each_bit(code, meaning):
    assert error_meaning(code) == meaning


# -- a meter left in the `TD1` mode; readings in the dark ---------------------------------------------

@pytest.mark.parametrize("ack", [b"\n", b"#\n"], ids=["bare LF", "#"])
def test_td0_comes_first_and_its_acknowledgement_may_be_either_modes(expected_protocol, clock, events, ack):
    """A meter left with `TD1` acknowledges settings with `#` (§15.3.9): `TD0` before anything else switches
    that off, whichever mode acknowledges `TD0` itself."""
    with expected_protocol([(b"TD0\n", ack)] + CONNECT[1:] + [READING]) as replay:
        reading = connect(replay.open_port, clock, events).read()
    assert reading.range_index == 3 and events == [] and replay.opens == 1


def test_a_td0_answered_otherwise_is_retried_then_named(expected_protocol, clock, events):
    with expected_protocol([(b"TD0\n", b"*\n")] * 3) as replay:
        with pytest.raises(DeviceError) as err:
            connect(replay.open_port, clock, events)
    assert str(err.value) == ("meter: connect failed 3 times; last: meter: 'TD0' answered '*', not the bare line "
                              "feed or the '#' that acknowledge it")


@pytest.mark.parametrize("range_index", [7, 5])
def test_an_underload_is_a_flagged_reading_below_the_floor_of_the_range(expected_protocol, clock, events,
                                                                        range_index):
    """`?32` (less light than the range resolves) is a reading in the dark, not a failure: the range the meter is
    on (`GR`) gives the floor (its last digit, full scale / 2000: 0.1 pA on range 7), the reading is the midpoint
    of [0, floor), flagged; nothing is retried."""
    script = CONNECT + [(b"MA;GR\n", b"?32\n"), (b"GR\n", f"{range_index}\n".encode()), READING]
    with expected_protocol(script) as replay:
        meter = connect(replay.open_port, clock, events)
        dark, lit = meter.read(), meter.read()
    floor = 2e-3 * 10.0 ** -range_index / 2000
    assert RANGE_FLOOR_A[range_index] == pytest.approx(floor, rel=1e-12)
    assert dark.underload and dark.floor_a == RANGE_FLOOR_A[range_index] and dark.range_index == range_index
    assert dark.photocurrent_a == pytest.approx(floor / 2, rel=1e-12)
    assert dark.illuminance_lx == pytest.approx(floor / 2 * CAL, rel=1e-12)
    assert not lit.underload and lit.floor_a is None
    assert events == [] and replay.opens == 1


def test_a_refused_setting_stops_the_connect(expected_protocol, clock, events):
    with expected_protocol(CONNECT[:5] + [(b"SN2000\n", b"?8\n")]) as replay:
        with pytest.raises(DeviceError, match=r"^meter: 'SN2000' answered '\?8': parameter out of limits$") as err:
            connect(replay.open_port, clock, events)
    assert not err.value.transient and events == []


def test_a_silent_meter_at_connect_is_asked_about_its_remote_mode(expected_protocol, clock, events):
    with expected_protocol([(b"TD0\n", b"")] * 3) as replay:
        with pytest.raises(DeviceError) as err:
            connect(replay.open_port, clock, events)
    assert str(err.value) == ("meter: connect failed 3 times; last: meter: no complete reply to 'TD0' within 0.2 s "
                              "(got b'') (is the meter's menu Mode set to \"Remote RS232\"?)")
    assert err.value.unanswered and not err.value.transient


# -- garbled, short or missing replies: transient, retried after a reconnect -------------------------

def test_a_setting_answered_otherwise_than_by_a_bare_line_feed_is_retried(expected_protocol, clock, events):
    script = CONNECT[:4] + [(b"SB1\n", b"OK\n")] + CONNECT
    with expected_protocol(script) as replay:
        connect(replay.open_port, clock, events).close()
    assert replay.opens == 2         # the connect was retried on a fresh port


def test_a_setting_never_acknowledged_is_a_clean_error(expected_protocol, clock, events):
    script = (CONNECT[:4] + [(b"SB1\n", b"OK\n")]) * 3
    with expected_protocol(script) as replay:
        with pytest.raises(DeviceError) as err:
            connect(replay.open_port, clock, events)
    assert str(err.value) == ("meter: connect failed 3 times; last: meter: 'SB1' answered 'OK' instead of the "
                              "bare line feed that acknowledges it")
    assert replay.opens == 3


@pytest.mark.parametrize("bad, message", [
    (b"+1.2345E-06\n", "'MA;GR' answered '+1.2345E-06', not '<current>;<range 0…7>'"),
    (b"+1.2345E-06;8\n", "'MA;GR' answered '+1.2345E-06;8', not '<current>;<range 0…7>'"),
    (b"1.2.3E-06;3\n", "'MA;GR' answered '1.2.3E-06;3', not '<current>;<range 0…7>'"),
    (b"nan;3\n", "'MA;GR' answered 'nan;3', not '<current>;<range 0…7>'"),
    (b"?x\n", "'MA;GR' answered '?x', not '<current>;<range 0…7>'"),
    (b"\xab\xb2\n", "garbled reply to 'MA;GR': b'\\xab\\xb2\\n'"),
    (b"+1.2345E", "no complete reply to 'MA;GR' within 0.6 s (got b'+1.2345E')"),
    (b"", "no complete reply to 'MA;GR' within 0.6 s (got b'')"),
])
def test_a_bad_reading_is_retried_after_a_reconnect(expected_protocol, clock, events, bad, message):
    script = CONNECT + [(b"MA;GR\n", bad)] + CONNECT + [READING]
    with expected_protocol(script) as replay:
        meter = connect(replay.open_port, clock, events)
        reading = meter.read()
        meter.close()
    assert reading.photocurrent_a == 1.2345e-6 and reading.range_index == 3
    assert events == [("retry", dict(device="meter", what="MA;GR", attempt=1, error=f"meter: {message}")),
                      ("reconnect", dict(device="meter", what="MA;GR", attempt=1))]


def test_requests_never_write_the_eeprom_or_need_a_code(expected_protocol, clock, events):
    script = CONNECT + [READING, (b"GR\n", b"3\n")]
    with expected_protocol(script) as replay:
        meter = connect(replay.open_port, clock, events)
        meter.read()
        meter.measuring_range()
    sent = {request.decode()[:2] for request, _ in replay.written}
    assert sent == {"TD", "GI", "TT", "GK", "SB", "SN", "MA", "GR"}
    assert not sent & {"SP", "SC", "SE", "TS", "TE", "SF", "TA", "RA", "ST"}
