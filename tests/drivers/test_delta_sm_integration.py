"""Delta SM lamp-supply driver against its protocol peer over loopback TCP, with every fault; and the
peer's SCPI parser.

pyserial's `socket://` close sleeps 0.3 s of wall time, so the peer tests
share one peer and one connected driver (reset before each test) and the
fault tests wait at most a 0.2 s timeout per lost reply.
"""

import threading
from itertools import pairwise

import pytest

from rig.config.rigfile import RigConfig, RigConfigError, load_rig_config
from rig.core.errors import DeviceError
from rig.drivers.delta_sm import DeltaSM
from rig.drivers.interfaces import OutputLoss
from rig.drivers.retry import RetryPolicy
from rig.physics.brdf_models import get_model
from rig.simulators.delta_sm_peer import DeltaSMPeer
from rig.simulators.delta_sm_scpi import header_matches
from rig.simulators.world import SimWorld

FAST = 0.2                     # s; fault tests wait out this timeout per lost reply
PATIENT = 10.0                 # s; drivers no test loses a reply to
ATTEMPTS = 2
WATCHDOG_S = 10.0
#: The rig file's lamp settings the driver gets (the peer is a 15 V / 10 A supply).
OPTIONS = dict(current_a=4.17, current_limit_a=9.0, watchdog_s=WATCHDOG_S, ramp_s=0.0, voltage_limit_v=14.0)


@pytest.fixture(scope="module", autouse=True)
def no_leaked_threads():
    before = set(threading.enumerate())
    yield
    assert set(threading.enumerate()) <= before


@pytest.fixture(scope="module")
def world() -> SimWorld:
    return SimWorld(RigConfig(), get_model("lambert"), {"kd": 0.5})


@pytest.fixture(scope="module")
def peer(world):
    with DeltaSMPeer(world) as peer:
        yield peer


@pytest.fixture(scope="module")
def shared_lamp(peer, world):
    lamp = DeltaSM(peer.url, clock=world.clock, timeout_s=FAST, retry=RetryPolicy(attempts=ATTEMPTS), **OPTIONS)
    # The fault tests count exchanges: a feed in a retry's back-off would take the injected fault. The
    # shared driver does not feed (the fixture below stops the watchdog); the watchdog tests at the end
    # use drivers of their own.
    lamp._cancel_feed()
    yield lamp
    lamp.close()



def ask(peer: DeltaSMPeer, *lines: str) -> list[str | None]:
    return [peer.answer(line.encode("ascii")) for line in lines]


@pytest.fixture
def lamp(shared_lamp, peer, world, events):
    """The shared driver on a supply reset to its state after connect, with a new, cold lamp."""
    ask(peer, "*RST", "OUTP OFF", "*CLS", "SYST:REM:CV REM", "SYST:REM:CC REM", "SYST:LIM:CURR 9,ON",
        "SYST:LIM:VOLT 14,ON", "SOUR:VOLT 14", "SYST:COMM:WAT STOP")
    world.lamp.replace()
    shared_lamp.events = lambda kind, **fields: events.append((kind, fields))
    return shared_lamp


def test_peer_identity_remote_hand_over_and_close(lamp, peer, world):
    assert lamp.identity() == "DELTA ELEKTRONIKA BV,SM15-CP-10,000000000001,SIM_P0150,0"
    ask(peer, "SYST:REM:CV LOC", "SYST:REM:CC LOC", "SOUR:VOLT 0")
    second = DeltaSM(peer.url, clock=world.clock, timeout_s=FAST, **OPTIONS)
    assert (peer.remote["CV"], peer.remote["CC"]) == (True, True)
    assert peer.voltage_v == 14.0 and peer.limits["V"] == (14.0, True)     # the lamp's limit, not the maximum
    second.set_output(True)
    second.close()
    assert (peer.remote["CV"], peer.remote["CC"]) == (False, False)       # front panel again...
    assert not peer.watchdog_armed                         # disarmed at a clean end
    assert peer.output_on                                  # ...and the output left as it was


def test_constant_current_ramp_has_no_overshoot_and_warms_the_filament(lamp, world, monkeypatch):
    setpoints = []
    program = world.lamp.set_current
    monkeypatch.setattr(world.lamp, "set_current",
                        lambda i, ramp_s=0.0: (setpoints.append((world.clock.now(), i)), program(i, ramp_s)))
    lamp.set_current(0.0)
    lamp.set_output(True)
    t0 = world.clock.now()
    lamp.set_current(4.17, ramp_s=5.0)
    assert world.clock.now() - t0 == pytest.approx(5.0)
    times, currents = zip(*setpoints[1:])
    assert len(currents) == 50 and currents[-1] == pytest.approx(4.17, abs=1e-12)
    assert max(currents) == pytest.approx(4.17, abs=1e-12)                  # no overshoot
    assert all(b >= a for a, b in pairwise(currents))
    assert [t - t0 for t in times] == pytest.approx([0.1 * k for k in range(1, 51)])
    world.clock.sleep(2.0)
    current, voltage = lamp.measure_current_a(), lamp.measure_voltage_v()
    assert current == pytest.approx(4.17, abs=1e-12)
    assert voltage == pytest.approx(12.0, abs=1e-4)        # hot filament: rated voltage at nominal current
    assert voltage / current == pytest.approx(world.lamp.resistance_ohm(), abs=1e-4)


def test_output_on_off_and_measurements_follow_the_filament(lamp, world):
    lamp.set_current(4.17)
    assert lamp.output_is_on() is False
    assert (lamp.measure_current_a(), lamp.measure_voltage_v()) == (0.0, 0.0)
    lamp.set_output(True)                                  # switching on cold at full current: inrush
    assert lamp.output_is_on() is True
    assert lamp.measure_voltage_v() == pytest.approx(4.17 * world.lamp.cold_resistance_ohm, abs=1e-4)
    world.clock.sleep(0.15)
    assert 1.3 < lamp.measure_voltage_v() < 12.0           # heating up: the voltage transient
    lamp.set_output(False)
    assert lamp.output_is_on() is False and world.lamp.relative_output() == 0.0


@pytest.mark.parametrize("fault", ["no_reply", "garbled", "short", "disconnect"])
def test_transient_fault_is_retried_after_a_reconnect(lamp, peer, events, fault):
    lamp.set_current(4.17)
    lamp.set_output(True)
    peer.inject(fault)
    assert lamp.measure_current_a() == pytest.approx(4.17, abs=1e-12)
    assert [kind for kind, _ in events] == ["retry", "reconnect"]
    assert events[0][1]["what"] == "MEASure:CURrent?"


@pytest.mark.parametrize("fault, answer", [("no_reply", "got b'')"), ("garbled", "garbled reply"),
                                           ("short", "got b'4.1')"), ("disconnect", "connection lost")])
def test_persistent_fault_names_device_command_and_answer(lamp, peer, fault, answer):
    lamp.set_current(4.17)
    lamp.set_output(True)
    peer.inject(fault, count=ATTEMPTS)
    with pytest.raises(DeviceError) as err:
        lamp.measure_current_a()
    message = str(err.value)
    assert not err.value.transient
    assert message.startswith(f"lamp: MEASure:CURrent? failed {ATTEMPTS} times") and answer in message


def test_a_fault_after_a_setting_resends_it(lamp, peer, events):
    peer.inject("garbled")                                 # hits the error read after the setting
    lamp.set_current(2.5)
    assert peer.current_a == 2.5
    assert events[0][1]["what"] == "SOURce:CURrent 2.5000"


def test_error_queue_entry_is_a_persistent_refusal(lamp, peer, events):
    peer.inject("error_queue")
    with pytest.raises(DeviceError) as err:
        lamp.set_output(True)
    assert not err.value.transient and events == []
    assert str(err.value) == "lamp: 'OUTPut ON' refused: -300,Device-specific error"
    lamp.set_output(True)                                  # the queue was drained
    assert peer.output_on


@pytest.mark.parametrize("current_a", [-0.5, 10.5])
def test_unreachable_current_is_refused_before_the_ramp_starts(lamp, peer, world, current_a):
    t0 = world.clock.now()
    with pytest.raises(DeviceError, match=r"current .* A outside 0 … 9 A \(the current limit\)"):
        lamp.set_current(current_a, ramp_s=5.0)
    assert peer.current_a == 0.0 and world.clock.now() == t0


def test_out_of_range_setting_is_refused_by_the_supply(lamp, monkeypatch):
    monkeypatch.setattr(lamp, "current_limit_a", 20.0)     # a driver that believed a larger limit
    with pytest.raises(DeviceError, match=r"'SOURce:CURrent 9.5000' refused: -222,Data out of range"):
        lamp.set_current(9.5)


def test_burn_out_shows_as_no_current_at_the_voltage_limit(lamp, peer, world):
    lamp.set_current(4.17)
    lamp.set_output(True)
    peer.inject("burnout")
    assert lamp.measure_current_a() == 0.0
    assert lamp.measure_voltage_v() == 14.0                # the lamp's voltage limit, not the supply's maximum
    assert world.illuminance_normal_lx() == 0.0
    world.lamp.replace()
    assert lamp.measure_current_a() == pytest.approx(4.17, abs=1e-12)


def test_switching_off_is_confirmed_by_read_back_despite_stale_errors(lamp, peer, events):
    lamp.set_output(True)
    peer.inject("error_queue", count=2)
    lamp.set_output(False)
    assert not peer.output_on
    assert events == [("device_errors", {"device": "lamp", "what": "OUTPut OFF",
                                         "errors": ["-300,Device-specific error"] * 2})]


def test_switching_off_gets_more_attempts_than_other_commands(lamp, peer, events):
    lamp.set_output(True)
    for fault in ("no_reply", "disconnect", "garbled"):    # one more than ATTEMPTS
        peer.inject(fault)
    lamp.set_output(False)
    assert not peer.output_on
    assert [kind for kind, _ in events].count("retry") == 3


# -- the peer's SCPI parser --------------------------------------------------------------------
def test_peer_accepts_long_short_and_any_case(lamp, peer):
    for line, value in (("SOUR:CURR 4.17", 4.17), ("source:current 2.5", 2.5), ("Sour:Cur 1", 1.0),
                        (":SOURce:CURrent 3", 3.0)):
        ask(peer, line)
        assert peer.current_a == value
    assert ask(peer, "MEAS:VOLT?", "meas:curr?", "SOUR:CURR?", "outp?", "*idn?", "syst:rem:cv?", "SYST:ERR?") == \
        ["0.0000", "0.0000", "3.0000", "0", peer.identity, "REMote", "0,None"]


def test_peer_queues_scpi_errors(lamp, peer):
    ask(peer, "SYST:REM:CC LOC")
    assert ask(peer, "VOLT 3", "SOUR:CURR 1", "SYST:REM:CC REM", "SOUR:CURR 11", "SOUR:CURR abc", "OUTP maybe",
               "MEAS:CURR? 2", "SOUR:CURR", "MEAS:VOLT") == [None] * 9
    assert ask(peer, *["SYST:ERR?"] * 9) == [
        "-113,Undefined header", "-221,Settings conflict", "-222,Data out of range", "-104,Data type error",
        "-224,Illegal parameter value", "-108,Parameter not allowed", "-109,Missing parameter",
        "-113,Undefined header", "0,None"]
    assert peer.current_a == 0.0


def test_peer_error_queue_holds_ten_entries_and_ignores_more(lamp, peer):
    """Manual §5.6.7: "The error queue can contain maximum 10 errors; more error messages are ignored."""
    ask(peer, *["BOGUS"] * 11, "SOUR:CURR abc")
    assert ask(peer, *["SYST:ERR?"] * 11) == ["-113,Undefined header"] * 10 + ["0,None"]
    peer.inject("error_queue")
    ask(peer, "*CLS")
    assert ask(peer, "SYST:ERR?") == ["0,None"]


def test_peer_stop_is_idempotent_and_refuses_unknown_faults():
    peer = DeltaSMPeer(SimWorld(RigConfig(), get_model("lambert"), {"kd": 0.5}))
    with pytest.raises(ValueError, match="unknown fault"):
        peer.inject("fire")
    assert peer.start().startswith("socket://127.0.0.1:")
    peer.stop()
    peer.stop()


# -- the watchdog, end to end ------------------------------------------------------------------------
@pytest.fixture
def guarded(peer, world, lamp):
    """A second driver with a 0.5 s watchdog (the shared one is closed at the module's end). No reply is lost to
    it, so it waits as long as a loaded machine may take to answer: a retry after FAST would be an event of its own."""
    guarded = DeltaSM(peer.url, clock=world.clock, timeout_s=PATIENT, **(OPTIONS | dict(watchdog_s=0.5)))
    yield guarded
    guarded.close()


def test_the_keep_alive_keeps_the_output_on_through_long_sleeps(guarded, peer, world):
    guarded.set_current(4.17)
    guarded.set_output(True)
    world.clock.sleep(1.5)                                 # 3 × the watchdog time, no command of ours
    peer.check_watchdog()
    assert peer.output_on and peer.watchdog_armed


def test_without_feeds_the_supply_switches_itself_off_and_the_driver_hears_of_it(guarded, peer, world, events):
    guarded.set_current(4.17)
    guarded.set_output(True)
    guarded.events = lambda kind, **fields: events.append((kind, fields))
    world.clock.advance(0.6)                               # the process is frozen: time passes, no feeds
    peer.check_watchdog()
    assert not peer.output_on and world.lamp.relative_output() == 0.0
    world.clock.sleep(0.2)                                 # alive again: the next feed finds it expired
    assert [kind for kind, _ in events] == ["watchdog_expired"]
    assert peer.watchdog_armed and not guarded.output_is_on()


def test_a_new_session_hears_that_the_previous_one_died(peer, world, lamp, events):
    first = DeltaSM(peer.url, clock=world.clock, timeout_s=FAST, **(OPTIONS | dict(watchdog_s=0.5)))
    first.set_output(True)
    first.link.close()                                     # kill -9: no close(), the feed stays registered
    first._cancel_feed()                                   # ...but its process is gone
    world.clock.advance(1.0)
    second = DeltaSM(peer.url, clock=world.clock, timeout_s=FAST, **OPTIONS)
    second.events = lambda kind, **fields: events.append((kind, fields))
    second.close()
    assert [kind for kind, _ in events] == ["watchdog_expired_before_connect"]
    assert not peer.output_on


def test_switching_off_ramps_the_current_down_before_output_off(peer, world, lamp):
    ramping = DeltaSM(peer.url, clock=world.clock, timeout_s=FAST, **(OPTIONS | dict(ramp_s=5.0)))
    try:
        ramping.set_current(4.17)
        ramping.set_output(True)
        t0 = world.clock.now()
        ramping.set_output(False)
        assert world.clock.now() - t0 == pytest.approx(2.0)       # the switch-off ramp is at most 2 s
        assert peer.current_a == 0.0 and not peer.output_on
    finally:
        ramping.close()


def test_the_peer_passes_the_drivers_replays():
    """The exchanges the driver's in-memory tests script (from the manual's examples) are what the rebuilt
    peer answers, line for line, when it is configured as the manual's example supply."""
    from shared import DELTA_SM_CLOSE as CLOSE
    from shared import DELTA_SM_CONNECT as CONNECT
    from shared import DELTA_SM_IDN as IDN

    maker, model, serial, firmware, _ = IDN.split(",")
    peer = DeltaSMPeer(SimWorld(RigConfig(), get_model("lambert"), {"kd": 0.5}), model=model, serial=serial,
                       firmware=firmware, max_voltage_v=500.0, max_current_a=90.0)
    for line, reply in CONNECT + CLOSE:
        assert peer.answer(line.encode("ascii")) == reply, line


# -- a large supply: the lamp's voltage limit, never the supply's maximum ----------------------------------------
def numbers_sent(peer: DeltaSMPeer, header: tuple[str, ...]) -> list[float]:
    """The values of every `header <value>[,...]` line the peer received (any case, long or short form)."""
    values = []
    for line in peer.received:
        head, _, param = line.strip().partition(" ")
        if param and header_matches(head.removeprefix(":").split(":"), header):
            values.append(float(param.partition(",")[0]))
    return values


def test_on_a_500_v_supply_no_voltage_above_the_lamps_limit_is_ever_sent(world):
    rig = RigConfig.model_validate({"simulated": False, "lamp": {"voltage_limit_v": 14.0, "ramp_s": 0.5},
                                    "devices": {"lamp": {"address": "socket://127.0.0.1:1"}}})
    with DeltaSMPeer(world, model="SM500-CP-90") as big:
        lamp = DeltaSM.from_rig(clock=world.clock, settings=rig.lamp, address=big.url, timeout_s=FAST)
        try:
            lamp.set_current(0.0)
            lamp.set_output(True)
            lamp.set_current(rig.lamp.current_a, ramp_s=rig.lamp.ramp_s)
            world.lamp.burn_out()                                  # an open filament sees the voltage setpoint
            assert lamp.measure_voltage_v() == pytest.approx(14.0, abs=1e-9)
            lamp.set_output(False)
        finally:
            lamp.close()
            world.lamp.replace()
        assert big.max_voltage_v == 500.0 and big.limits["V"] == (14.0, True)
        sent = numbers_sent(big, ("SOURce", "VOLtage")) + numbers_sent(big, ("SYSTem", "LIMits", "VOLtage"))
        assert sent and max(sent) <= 14.0


def test_without_the_voltage_limit_a_real_rig_file_is_refused_naming_the_key(tmp_path):
    path = tmp_path / "lab.yaml"
    path.write_text("simulated: false\nlamp: {current_a: 4.17}\ndevices: {lamp: {address: 'socket://10.0.0.5:8462'}}\n")
    with pytest.raises(RigConfigError, match=r"key 'lamp.voltage_limit_v' is required with a delta-sm lamp supply"):
        load_rig_config(path)
    assert RigConfig().lamp.voltage_limit_v == 14.0                # the simulated 12 V lamp's, stated


def test_without_the_voltage_limit_the_driver_refuses_to_connect(world):
    settings = RigConfig().lamp.model_copy(update={"voltage_limit_v": None})
    with DeltaSMPeer(world, model="SM500-CP-90") as big:
        with pytest.raises(DeviceError, match=r"set lamp.voltage_limit_v in the rig file"):
            DeltaSM.from_rig(clock=world.clock, settings=settings, address=big.url, timeout_s=FAST)
        assert list(big.received) == []                            # nothing was sent


# -- why the lamp gets no current, as the supply tells it ----------------------------------------------------------
def test_an_open_interlock_or_a_remote_shut_down_is_named_and_reported_once(lamp, peer, events):
    lamp.set_current(4.17)
    lamp.set_output(True)
    assert lamp.output_loss() is None                              # on and nothing blocks: the lamp is to blame
    peer.set_interlock(True)
    peer.warn("Interlock open")
    assert lamp.measure_current_a() == 0.0 and lamp.output_is_on()  # the output setting stays on
    loss = lamp.output_loss()
    assert loss == OutputLoss("the supply blocks its output: interlock open (the supply's interlock input) "
                              "(warnings: 301,Interlock open)", restart=False)
    assert lamp.output_loss().reason.endswith("interlock input)")   # the warning was read once
    ask(peer, "SYSTem:RSD ON")
    assert "interlock open (the supply's interlock input); remote shut-down (RSD) active" in lamp.output_loss().reason
    assert [f["status_a"] for kind, f in events if kind == "lamp_output_blocked"] == [8192 + 2048, 8192 + 2048 + 4096]
    peer.set_interlock(False)
    ask(peer, "SYSTem:RSD OFF")
    assert lamp.measure_current_a() == pytest.approx(4.17, abs=1e-12) and lamp.output_loss() is None


def test_an_output_switched_off_at_the_supply_is_not_switched_on_again_by_rig(lamp, peer):
    ask(peer, "SYST:COMM:WAT SET,10000")                            # armed, as after connect (the fixture stops it)
    lamp.set_output(True)
    ask(peer, "OUTPut OFF")                                        # the front panel, the web page, another client
    loss = lamp.output_loss()
    assert loss is not None and not loss.restart and "switched off at the supply, not by rig" in loss.reason
    lamp.set_output(False)
    assert lamp.output_loss() is None                              # rig switched it off: nothing was lost


def test_an_output_the_watchdog_switched_off_may_be_switched_on_again(guarded, peer, world, events):
    guarded.events = lambda kind, **fields: events.append((kind, fields))
    guarded.set_current(4.17)
    guarded.set_output(True)
    world.clock.advance(0.6)                                       # frozen longer than the 0.5 s watchdog
    peer.check_watchdog()
    loss = guarded.output_loss()                                   # noticed here, before any feed
    assert loss is not None and loss.restart and "communication watchdog switched the output off" in loss.reason
    assert [kind for kind, _ in events] == ["watchdog_expired"] and peer.watchdog_armed
    guarded.set_output(True)
    assert guarded.output_loss() is None and peer.output_on
