"""P-9710 optometer: the driver against its pty peer, with every fault; the peer's own answers, byte for byte.

Provenance of the peer replays (public sources): real captures of a firmware 5.6 unit in github
matusm/Bev.Instruments.P9710.Detector (doc/dumpDetector1.txt: `GC0`→80, `GC6`→141, `GC7`→204; doc/BruteForce.txt:
`ST`→`?4` without the right `RA` code; `GI`/`TF`/`TT`/`GK` via matusm/Bev.Instruments.P9710 P9710.cs), and the
manual's constructed examples (P-9710 Operating Manual V1.20 §15: `SN1000`→LF, `MV;GD`, spacers, `?x` codes).
"""

import os
import re
import time

import pytest
import serial
from shared import ANSWERED_S, SILENCE_S
from shared import P9710_CONNECT as CONNECT
from shared import P9710_READING as READING

from rig.config.rigfile import MeterConfig, RigConfig, SimulationConfig
from rig.core.errors import DeviceError
from rig.drivers.p9710 import P9710, error_meaning
from rig.physics.brdf_models import get_model
from rig.simulators.faults import METER_FAULTS
from rig.simulators.p9710_peer import P9710Peer, range_for
from rig.simulators.world import SimWorld

CAL = 1.0e9
#: The reply timeout of a reading where replies are lost: 0.2 s integration + 0.05 s autorange + 0.2 s link
#: (SILENCE_S).
READ_TIMEOUT = "0.45 s"
#: Each transient fault and what the driver's error says the meter answered (a regex).
FAULT_REPLIES = pytest.mark.parametrize("fault, reply", [
    pytest.param("no_reply", re.escape(f"no complete reply to 'MA;GR' within {READ_TIMEOUT} (got b'')"),
                 id="no_reply"),
    pytest.param("garbled", re.escape("garbled reply to 'MA;GR': b'\\x"), id="garbled"),
    pytest.param("short", re.escape(f"no complete reply to 'MA;GR' within {READ_TIMEOUT} (got b'+")
                 + r"\d\.\d{4}E-06;\d'\)", id="short"),
])
NUMBER = rb"[+-]\d\.\d{4}E[+-]\d\d"



def lit_world(**sim) -> SimWorld:
    """A warm, steady lamp at nominal current."""
    cfg = RigConfig(meter=MeterConfig(calibration_lx_per_a=CAL),
                    simulation=SimulationConfig(**{"warmup_amplitude": 0.0, "drift_per_hour": 0.0, **sim}))
    world = SimWorld(cfg, get_model("lambert"), {"kd": 0.5})
    world.lamp.set_current(cfg.lamp.current_a, 0)
    world.lamp.switch(True)
    return world


@pytest.fixture
def world():
    return lit_world()


@pytest.fixture
def peer(world, no_leaks):
    with P9710Peer(world) as p:
        yield p



def connect(path, world, events, cal=CAL, timeout_s=ANSWERED_S) -> P9710:
    meter = P9710(path, calibration_lx_per_a=cal, clock=world.clock, timeout_s=timeout_s, integration_s=0.2,
                  autorange_s=0.05)
    meter.events = lambda kind, **fields: events.append((kind, fields))
    return meter


@pytest.fixture
def meter(peer, world, events):
    m = connect(peer.path, world, events)
    yield m
    m.close()


@pytest.fixture
def silent_meter(peer, world, events):
    """A meter whose lost replies time out quickly (SILENCE_S)."""
    m = connect(peer.path, world, events, timeout_s=SILENCE_S)
    yield m
    m.close()


@pytest.fixture
def exchange(peer):
    """`exchange(request) -> reply`: raw bytes to and from the peer over its pty (one LF-terminated reply)."""
    with serial.Serial(peer.path, 9600, timeout=2) as port:
        def one(request: bytes) -> bytes:
            port.write(request)
            return port.read_until(b"\n")
        yield one


# -- driver against the simulated meter ----------------------------------------------------------

@pytest.mark.parametrize("identity", ["P9710 V5.6", "P-9710 4.7"])
def test_connect_checks_identity_and_sets_autorange_and_integration(world, events, no_leaks, identity):
    with P9710Peer(world, identity=identity) as peer:
        meter = connect(peer.path, world, events)
        meter.close()
    assert meter.identity() == f"Gigahertz-Optik {identity} SN 1875 detector VL__"
    assert peer.autorange and peer.integration_steps == 2000


@pytest.mark.parametrize("driver_cal", [CAL, 1.02 * CAL])
def test_reading_is_photocurrent_times_configured_factor_with_its_range(events, no_leaks, driver_cal):
    """The factor comes from the driver's configuration; a wrong one scales the result."""
    world = lit_world(meter_noise_rel=0.0)
    with P9710Peer(world) as peer:
        meter = connect(peer.path, world, events, cal=driver_cal)
        reading = meter.read()
        meter.close()
    truth = world.illuminance_normal_lx()
    assert reading.calibration_lx_per_a == driver_cal
    assert reading.photocurrent_a == pytest.approx(truth / CAL, rel=1e-4)
    assert reading.illuminance_lx == pytest.approx(truth * driver_cal / CAL, rel=1e-4)
    assert reading.range_index == range_for(truth / CAL) == peer.range == 2


def test_readings_scatter_with_the_configured_noise(meter, world):
    deviations = []
    for _ in range(50):
        reading = meter.read()
        deviations.append(reading.illuminance_lx / world.illuminance_normal_lx() - 1)
    noise = world.config.simulation.meter_noise_rel
    mean = sum(deviations) / len(deviations)
    std = (sum((d - mean) ** 2 for d in deviations) / (len(deviations) - 1)) ** 0.5
    assert abs(mean) < 4 * noise / len(deviations) ** 0.5
    assert 0.6 * noise < std < 1.4 * noise


def test_autorange_follows_a_jump_within_the_reading(meter, world, events):
    world.lamp.set_current(0.2 * world.config.lamp.current_a, 0)
    dim = meter.read()
    assert dim.range_index == meter.measuring_range() == range_for(dim.photocurrent_a) == 4
    world.lamp.set_current(world.config.lamp.current_a, 0)
    t0 = world.clock.now()
    bright = meter.read()
    assert bright.illuminance_lx == pytest.approx(world.illuminance_normal_lx(), rel=0.01)
    assert bright.range_index == range_for(bright.photocurrent_a) == 2
    assert world.clock.now() - t0 == pytest.approx(0.2 + 2 * 0.02)      # integration + two range steps
    assert events == []


def test_readings_cost_the_integration_time_in_rig_time_not_wall_time(meter, world, monkeypatch):
    """The meter integrates before answering (the peer spends rig time); nothing sleeps in wall time."""
    meter.read()                          # the autoranger settles first
    wall_sleeps = []
    monkeypatch.setattr(time, "sleep", wall_sleeps.append)
    t_rig = world.clock.now()
    for _ in range(20):
        meter.read()
    assert world.clock.now() - t_rig == pytest.approx(20 * 0.2)
    assert wall_sleeps == []


def test_more_light_than_the_top_range_holds_is_a_persistent_error(world, events, no_leaks):
    with P9710Peer(world, responsivity_a_per_lx=1e-6) as peer:          # 5 mA > 2 mA
        meter = connect(peer.path, world, events)
        with pytest.raises(DeviceError) as err:
            meter.read()
        meter.close()
    assert str(err.value) == f"meter: 'MA;GR' answered '?16': {error_meaning(16)}"
    assert not err.value.transient and events == []


def test_a_reading_in_the_dark_is_below_the_floor_of_the_most_sensitive_range(meter, world, events):
    """Lamp off: the autoranger ends on range 7, whose floor (0.1 pA) the meter cannot resolve (`?32`); the
    reading is the floor's midpoint, flagged, and the meter reads on once the light is back."""
    world.lamp.switch(False)
    dark = meter.read()
    assert dark.underload and dark.range_index == 7 and dark.floor_a == pytest.approx(1e-13, rel=1e-12)
    assert dark.photocurrent_a == pytest.approx(0.5e-13, rel=1e-12)
    world.lamp.switch(True)
    assert not meter.read().underload and events == []


def test_a_meter_left_in_the_td1_mode_is_switched_back_at_connect(world, events, no_leaks):
    """A meter powered up with `#`/`*` acknowledgements (§15.3.9 `TD1`) answers `SB1` with `#`: the driver's `TD0`
    comes first, so it connects, reads, and leaves the meter in the plain mode."""
    with P9710Peer(world, acknowledge_chars=True) as peer:
        meter = connect(peer.path, world, events)
        reading = meter.read()
        meter.close()
    assert not peer.acknowledge_chars and peer.autorange and peer.integration_steps == 2000
    assert reading.illuminance_lx == pytest.approx(world.illuminance_normal_lx(), rel=0.01) and events == []


def test_an_injected_overload_is_not_retried(meter, peer, world, events):
    peer.inject("overload")
    with pytest.raises(DeviceError, match=r"answered '\?16': input signal overload") as err:
        meter.read()
    assert not err.value.transient and events == []
    assert meter.read().illuminance_lx == pytest.approx(world.illuminance_normal_lx(), rel=0.01)


@FAULT_REPLIES
def test_each_transient_fault_costs_one_retry(silent_meter, peer, world, events, fault, reply):
    peer.inject(fault)
    assert silent_meter.read().illuminance_lx == pytest.approx(world.illuminance_normal_lx(), rel=0.01)
    (retry, retry_fields), (reconnect, _) = events
    assert (retry, reconnect) == ("retry", "reconnect")
    assert retry_fields["what"] == "MA;GR" and re.match(f"meter: {reply}", retry_fields["error"])


def test_a_reconnect_restores_settings_changed_at_the_front_panel(meter, peer, world, events):
    peer.autorange, peer.range, peer.integration_steps = False, 7, 1
    peer.inject("garbled")
    reading = meter.read()
    assert reading.illuminance_lx == pytest.approx(world.illuminance_normal_lx(), rel=0.01)
    assert peer.autorange and peer.integration_steps == 2000 and reading.range_index == 2
    assert [kind for kind, _ in events] == ["retry", "reconnect"]


@FAULT_REPLIES
def test_a_lasting_fault_is_a_clean_persistent_error(silent_meter, peer, world, events, fault, reply):
    peer.inject(fault, count=3)
    with pytest.raises(DeviceError) as err:
        silent_meter.read()
    assert re.match(f"meter: MA;GR failed 3 times; last: meter: {reply}", str(err.value))
    assert err.value.device == "meter" and not err.value.transient and err.value.unanswered
    assert [kind for kind, _ in events] == ["retry", "reconnect"] * 2
    assert silent_meter.read().illuminance_lx == pytest.approx(world.illuminance_normal_lx(), rel=0.01)


# -- the peer itself, byte for byte ----------------------------------------------------------------

def test_the_peer_passes_the_drivers_replays(exchange):
    """The driver's in-memory connect script (a real unit's answers), then a reading in the manual's format."""
    for request, reply in CONNECT:
        assert exchange(request) == reply
    assert re.fullmatch(NUMBER + rb";[0-7]\n", exchange(READING[0]))


@pytest.mark.parametrize("request_, reply", [
    (b"GI\n", b"P9710 V5.6\n"), (b"TF\n", b"521\n"), (b"TT\n", b"1875\n"), (b"GK\n", b"VL__\n"),
    (b"GC0\n", b"80\n"), (b"GC6\n", b"141\n"), (b"GC7\n", b"204\n"), (b"ST\n", b"?4\n"),
], ids=lambda v: v.decode().strip() if isinstance(v, bytes) else v)
def test_real_captures(exchange, request_, reply):
    assert exchange(request_) == reply


def test_manual_examples(exchange):
    assert exchange(b"SN1000\n") == b"\n"
    assert exchange(b"GS3\n") == b"1000\n"
    assert exchange(b"SY1\n") == b"\n"             # §15.5.1's "synchronisation on" (SY is the wavelength)
    assert exchange(b"SD12\n") == b"\n"
    assert exchange(b"SB1\n") == b"\n"
    assert re.fullmatch(NUMBER + b";" + NUMBER + b"\n", exchange(b"MV;GD\n"))


@pytest.mark.parametrize("spacer", [b",", b" ", b";", b"\t", b""], ids=["comma", "space", "semicolon", "tab", "none"])
def test_answers_are_joined_by_the_spacer_between_their_commands(exchange, spacer):
    assert re.fullmatch(NUMBER + re.escape(spacer) + NUMBER + b"\n", exchange(b"MA" + spacer + b"MU\n"))
    assert exchange(b"SB1" + spacer + b"SN1000\n") == b"\n"       # spacers between settings: no answer


@pytest.mark.parametrize("request_, code", [
    (b"XX\n", 1), (b"1234\n", 1), (b"GI?\n", 1), (b"M" * 101 + b"\n", 1),
    (b"SNabc\n", 2), (b"SN\n", 2), (b"GI1\n", 2), (b"SB\n", 2),
    (b"SN0\n", 8), (b"SN60000\n", 8), (b"SR8\n", 8), (b"SB2\n", 8), (b"GC2048\n", 8), (b"GS8\n", 8),
    (b"RA1234\n", 4), (b"SE200\n", 4), (b"SP0\n", 4), (b"SC104\n", 4), (b"TS7\n", 4), (b"TE7\n", 4),
    (b"SF00.980\n", 4), (b"TA2.503\n", 4),
    (b"SN0;XX\n", 8), (b"XX;SN0\n", 1), (b"GI;XX\n", 1),           # one reply for the line: the first error
], ids=lambda v: repr(v.decode().strip())[:20] if isinstance(v, bytes) else str(v))
def test_errors_answer_their_code(exchange, request_, code):
    assert exchange(request_) == f"?{code}\n".encode()


def test_range_limits_answer_overload_and_underload(exchange, world):
    assert exchange(b"SB0;SR7\n") == b"\n"
    assert exchange(b"MA\n") == b"?16\n"            # 5 µA on the 200 pA range
    assert exchange(b"SR0;MA;GR\n").endswith(b";0\n")   # fixed on range 0
    world.lamp.switch(False)
    assert exchange(b"SB1;MA\n") == b"?32\n"        # nothing on the most sensitive range
    assert exchange(b"GR\n") == b"7\n"


def test_offset_battery_and_percent_of_range(exchange, no_leaks):
    assert exchange(b"MB\n") == b"100%\n"
    assert exchange(b"SB1\n") == b"\n"
    assert re.fullmatch(NUMBER + rb";\+\d\d\.\d\n", exchange(b"MA;GP\n"))
    assert exchange(b"SO1\n") == b"\n"               # offset = the last CW value
    assert float(exchange(b"MA\n")) == pytest.approx(0.0, abs=5e-6 * 0.02)
    assert exchange(b"SO0;GS2\n") == b"+0.0000E+00\n"
    assert exchange(b"\n") == b"\n"


def test_the_td1_mode_acknowledges_with_hash_and_answers_errors_with_star(world):
    """§15.3.9: `TD1` → "#" and "*" (error) as answer; answers with content are unchanged; `TD0` back to LF."""
    peer = P9710Peer(world, acknowledge_chars=True)
    replies = [peer.respond(request) for request in (b"SB1", b"SN1000;SB1", b"XX", b"SN0", b"GI", b"GR", b"TD0",
                                                     b"SB1", b"XX", b"TD1", b"")]
    assert replies == [b"#\n", b"#\n", b"*\n", b"*\n", b"P9710 V5.6\n", b"0\n", b"\n", b"\n", b"?1\n", b"#\n",
                       b"#\n"]
    peer.inject("overload")
    assert peer.respond(b"MA") == b"*\n"


def test_peer_listens_on_a_pty_and_names_its_faults(world, no_leaks):
    with P9710Peer(world) as peer:
        assert peer.url is not None and peer.url.startswith("/dev/pts/") and os.path.exists(peer.url)
    assert METER_FAULTS.transient == ("no_reply", "garbled", "short") and METER_FAULTS.other == ("overload",)
