"""P9710 optometer driver: the exact byte exchanges, replayed in memory.

The driver against its pty peer, with every fault, is in test_p9710_integration.py.
"""

import pytest

from rig.core.errors import DeviceError
from rig.drivers.p9710 import P9710
from rig.simulators.clock import SimClock

CAL = 1.0e9
CONNECT = [(b"GI\n", b"P9710 V5.6\n"), (b"TT\n", b"12345\n"), (b"GK\n", b"VL-3701\n"), (b"SB1\n", b"OK\n")]
MA_OK = (b"MA\n", b"1.2345E-06\n")


@pytest.fixture
def clock() -> SimClock:
    return SimClock()


@pytest.fixture
def events():
    return []


def connect(replay, clock, events, cal=CAL) -> P9710:
    meter = P9710("/dev/ttyUSB0", calibration_lx_per_a=cal, clock=clock, timeout_s=0.2, open_port=replay.open_port)
    meter.events = lambda kind, **fields: events.append((kind, fields))
    return meter


def requests(script):
    return [request for request, _ in script]


def test_connect_identity_and_reading_bytes(expected_protocol, clock, events):
    script = CONNECT + [MA_OK, (b"GR\n", b"3\n")]
    with expected_protocol(script) as replay:
        meter = connect(replay, clock, events)
        t0 = clock.now()
        reading = meter.read()
        assert meter.measuring_range() == 3
        meter.close()
    assert requests(replay.written) == requests(script)            # no MV, no stray bytes, LF only
    assert meter.identity() == "Gigahertz-Optik P9710 V5.6 SN 12345 detector VL-3701"
    assert reading.photocurrent_a == 1.2345e-6
    assert reading.illuminance_lx == pytest.approx(1.2345e-6 * CAL)
    assert reading.calibration_lx_per_a == CAL
    assert clock.now() - t0 == pytest.approx(0.2)  # one integration
    assert events == []


def test_another_instrument_is_refused_at_once(expected_protocol, clock, events):
    with expected_protocol([(b"GI\n", b"K8000 V1.0\n")]) as replay:
        with pytest.raises(DeviceError, match=r"meter: 'GI' answered 'K8000 V1.0': not a P9710") as err:
            connect(replay, clock, events)
    assert not err.value.transient
    assert requests(replay.written) == [b"GI\n"] and events == []


@pytest.mark.parametrize("bad, message", [
    (b"OVER\n", "overrange: 'MA' answered 'OVER'"),
    (b"UNDER\n", "underrange: 'MA' answered 'UNDER'"),
    (b"1.2.3E-06\n", "non-numeric reply to 'MA': '1.2.3E-06'"),
    (b"nan\n", "non-numeric reply to 'MA': 'nan'"),
    (b"ERR\n", "non-numeric reply to 'MA': 'ERR'"),
])
def test_bad_reading_is_retried_after_a_reconnect(expected_protocol, clock, events, bad, message):
    script = CONNECT + [(b"MA\n", bad)] + CONNECT + [MA_OK]
    with expected_protocol(script) as replay:
        meter = connect(replay, clock, events)
        reading = meter.read()
        meter.close()
    assert requests(replay.written) == requests(script)
    assert reading.photocurrent_a == 1.2345e-6
    assert events == [("retry", dict(device="meter", what="MA", attempt=1, error=f"meter: {message}")),
                      ("reconnect", dict(device="meter", what="MA", attempt=1))]
