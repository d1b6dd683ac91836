"""The SM15K peer against the manual's own examples ("Ethernet & Sequencer Programming SM15K", rev. July
2021, via github keklikyusuf/DeltaElektronika), in memory: `answer()` is what the TCP server calls per line."""

import pytest

from rig.config.rigfile import RigConfig
from rig.physics.brdf_models import get_model
from rig.simulators.delta_sm_peer import DeltaSMPeer
from rig.simulators.world import SimWorld


@pytest.fixture
def world() -> SimWorld:
    return SimWorld(RigConfig(), get_model("lambert"), {"kd": 0.5})


@pytest.fixture
def peer(world) -> DeltaSMPeer:
    return DeltaSMPeer(world, model="SM500-CP-90", serial="000010207248", firmware="H0_P0150",
                       max_voltage_v=500.0, max_current_a=90.0)


def ask(peer: DeltaSMPeer, *lines: str) -> list[str | None]:
    return [peer.answer(line.encode("ascii")) for line in lines]


def test_manual_examples(peer):
    assert ask(peer, "*IDN?") == ["DELTA ELEKTRONIKA BV,SM500-CP-90,000010207248,H0_P0150,0"]      # §5.1.1
    assert ask(peer, "SOURce:VOLtage:MAXimum?") == ["500"]                                            # §5.2.2
    assert ask(peer, "*RST", "SOURce:VOLtage 14", "SOURce:VOLtage?") == [None, None, "14.0000"]      # §5.2.7
    assert ask(peer, "SYSTem:ERRor?") == ["0,None"]                                                   # §5.6.7


def test_status_register_a_shows_cc_cv_and_output(peer, world):
    ask(peer, "*RST", "SOUR:VOLT 14", "SOUR:CURR 4.17")
    assert ask(peer, "STATus:REGister:A?") == ["0"]
    ask(peer, "OUTP ON")
    world.clock.sleep(2.0)                                 # a hot filament: constant current
    assert ask(peer, "STAT:REG:A?") == [str(8192 + 2)]
    ask(peer, "SOUR:VOLT 1")                               # the voltage setpoint now limits: CV
    assert ask(peer, "STAT:REG:A?") == [str(8192 + 1)]
    assert float(ask(peer, "MEASure:POWer?")[0]) == pytest.approx(world.lamp.voltage_v() *
                                                                  world.lamp.filament_current_a(), abs=0.01)


def test_watchdog_set_is_silent_and_the_query_tells_the_remaining_ms(peer, world):
    assert ask(peer, "SYSTem:COMmunicate:WATchdog?") == ["-1"]                   # B: off after power-on
    assert ask(peer, "SYSTem:COMmunicate:WATchdog set,1000") == [None]           # C
    world.clock.advance(0.177)
    assert ask(peer, "SYSTem:COMmunicate:WATchdog?") == ["823"]                  # D
    assert ask(peer, "SYSTem:COMmunicate:WATchdog set?") == ["1000"]
    world.clock.advance(0.5)
    ask(peer, "SYST:ERR?")                                                       # E: any valid command restarts it
    world.clock.advance(0.9)
    assert ask(peer, "SYST:COMM:WAT?") == ["100"]
    ask(peer, "SYST:COMM:WAT STOP")
    assert ask(peer, "SYST:COMM:WAT?") == ["-1"]                                 # J


def test_watchdog_expiry_switches_the_output_off_and_reads_0_once(peer, world):
    ask(peer, "*RST", "SOUR:VOLT 14", "SOUR:CURR 4.17", "OUTP ON", "SYST:COMM:WAT SET,500")
    world.clock.advance(0.6)                               # no command for longer than the watchdog
    peer.check_watchdog()
    assert not peer.output_on and not world.lamp.output_on
    assert peer.current_a == 4.17 and peer.voltage_v == 14.0   # only the output is switched off
    assert ask(peer, "SYST:COMM:WAT?", "SYST:COMM:WAT?") == ["0", "-1"]          # P, Q


def test_an_invalid_command_does_not_restart_the_watchdog_and_test_expires_it(peer, world):
    ask(peer, "OUTP ON", "SYST:COMM:WAT SET,100")
    world.clock.advance(0.09)
    ask(peer, "BOGUS")
    world.clock.advance(0.02)
    assert ask(peer, "OUTP?") == ["0"]                     # expired on arrival of this line
    ask(peer, "OUTP ON", "SYST:COMM:WAT TEST")            # K: 2.5 ms
    world.clock.advance(0.003)
    assert ask(peer, "OUTP?", "SYST:COMM:WAT?") == ["0", "0"]


@pytest.mark.parametrize("line", ["SYST:COMM:WAT SET,19", "SYST:COMM:WAT SET,10001", "SYST:COMM:WAT SET,x",
                                  "SYST:COMM:WAT SET", "SYST:COMM:WAT RUN"])
def test_watchdog_parameters_outside_the_manual_are_errors(peer, line):
    assert ask(peer, line) == [None]
    assert ask(peer, "SYST:ERR?")[0] != "0,None"
    assert ask(peer, "SYST:COMM:WAT?") == ["-1"]


def test_current_limit_bounds_the_setpoint(peer):
    ask(peer, "*RST", "SOUR:CURR 6")
    assert ask(peer, "SYSTem:LIMits:CURrent 4.6,ON", "SYSTem:LIMits:CURrent?") == [None, "4.6000"]
    assert peer.current_a == 4.6                           # lowered to the new limit
    assert ask(peer, "SOUR:CURR 4.7", "SYST:ERR?") == [None, "-222,Data out of range"]
    ask(peer, "SYST:LIM:CURR 4.6,OFF", "SOUR:CURR 4.7")
    assert peer.current_a == 4.7                           # a disabled limit does not bound
    assert ask(peer, "SYST:LIM:CURR 4.6", "SYST:ERR?") == [None, "-109,Missing parameter"]
    assert ask(peer, "SYST:LIM:CURR 91,ON", "SYST:ERR?") == [None, "-222,Data out of range"]


def test_rst_per_manual_table_5_1(peer):
    ask(peer, "SYST:REM:CV REM", "SYST:REM:CC REM", "SOUR:VOLT 14", "SOUR:CURR 4", "OUTP ON",
        "SYST:REM:CV LOC", "SYST:REM:CC:STAtus LOC")
    ask(peer, "*RST")
    assert (peer.voltage_v, peer.current_a, peer.remote) == (0.0, 0.0, {"CV": True, "CC": True, "CP": True})
    assert peer.output_on                                  # not in the manual's table: left as it was
