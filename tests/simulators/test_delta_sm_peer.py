"""The SM15K peer against the manual's own examples ("Ethernet & Sequencer Programming SM15K", rev. July
2021, via github keklikyusuf/DeltaElektronika), in memory: `answer()` is what the TCP server calls per line."""

import re
import socket

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


# -- the rest of the manual's command list ------------------------------------------------------------------------
def test_maxima_step_sizes_and_the_large_model_from_its_name(world):
    big = DeltaSMPeer(world, model="SM500-CP-90")
    assert ask(big, "SOUR:VOLT:MAX?", "SOUR:CURR:MAX?", "SOUR:POW:MAX?", "SOUR:CURR:NEG:MAX?",
               "SOUR:POW:NEG:MAX?") == ["500", "90", "15000", "-90", "-15000"]
    assert ask(big, "SOUR:VOLT:STE?") == [f"{500 / 65535:.15e}"]                 # §5.2.12: 15 decimals
    assert ask(big, "SYST:LIM:VOLT?", "SYST:LIM:CURR:NEG?") == ["500.0000", "-90.0000"]


def test_negative_and_power_setpoints_and_limits(peer):
    ask(peer, "*RST", "SOUR:CURR:NEG -5", "SOUR:POW 100", "SOUR:POW:NEG -100")
    assert ask(peer, "SOUR:CURR:NEG?", "SOUR:POW?", "SOUR:POW:NEG?") == ["-5.0000", "100.0000", "-100.0000"]
    assert ask(peer, "SOUR:CURR:NEG 5", "SYST:ERR?") == [None, "-222,Data out of range"]
    ask(peer, "SYST:LIM:CURR:NEG -2,ON")
    assert ask(peer, "SOUR:CURR:NEG?", "SYST:LIM:CURR:NEG?") == ["-2.0000", "-2.0000"]     # brought to the limit


def test_remote_shut_down_and_the_interlock_block_the_output_and_show_in_register_a(peer, world):
    ask(peer, "*RST", "SOUR:VOLT 14", "SOUR:CURR 4.17", "OUTP ON")
    world.clock.sleep(2.0)
    assert ask(peer, "STAT:REG:A?", "STAT:REG:B?") == [str(8192 + 2), "7"]       # B: CV, CC, CP remote after *RST
    ask(peer, "SYSTem:RSD ON")
    assert world.lamp.relative_output() == 0.0
    assert ask(peer, "STAT:REG:A?", "SYST:RSD?", "SYST:RSD:STAtus?", "OUTP?") == [str(8192 + 4096), "1", "1", "1"]
    ask(peer, "*RST")                                      # table 5.1: RSD off
    assert ask(peer, "SYST:RSD?") == ["0"]
    ask(peer, "SOUR:VOLT 14", "SOUR:CURR 4.17")
    peer.set_interlock(True)
    assert world.lamp.relative_output() == 0.0 and ask(peer, "STAT:REG:A?") == [str(8192 + 2048)]
    peer.set_interlock(False)
    assert world.lamp.filament_current_a() == pytest.approx(4.17, abs=1e-12)


def test_warnings_queue_like_errors(peer):
    assert ask(peer, "SYSTem:WARning?") == ["0,None"]                           # §5.6.8
    peer.warn("Interlock open")
    assert ask(peer, "SYST:WARN?", "SYST:WARN?") == ["301,Interlock open", "0,None"]


def test_the_ampere_hour_instrument_integrates_the_current(peer, world):
    ask(peer, "*RST", "SOUR:VOLT 14", "SOUR:CURR 4.17", "OUTP ON")
    assert ask(peer, "MEAS:INS AH,STATE?", "MEAS:INS AH,POS,TOTAL?") == ["OFF", f"{0:.15e}"]
    world.clock.sleep(5.0)
    ask(peer, "MEASure:INStrument AH,STATE,ON")
    world.clock.sleep(1800.0)
    total, hours, seconds, high = ask(peer, "MEAS:INS AH,POS,TOTAL?", "MEAS:INS AH,TIMEHR?", "MEAS:INS AH,TIMESEC?",
                                      "MEAS:INS AH,POS,IMAX?")
    assert float(total) == pytest.approx(4.17 / 2, rel=1e-6) and re.fullmatch(r"\d\.\d{15}e[+-]\d\d", total)
    assert (hours, seconds, high) == ("0.500", "1800.0", "4.1700")
    assert ask(peer, "MEAS:INS AH,BOGUS?", "SYST:ERR?") == [None, "-224,Illegal parameter value"]


def test_clock_password_user_data_and_front_panel(peer, world):
    assert ask(peer, "SYST:TIM?", "SYST:DAT?") == ["UNKNOWN", "UNKNOWN"]           # §5.6.6
    ask(peer, "SYST:TIM 9,10,0", "SYST:DAT 2021,9,8")
    world.clock.sleep(65.0)
    assert ask(peer, "SYST:TIM?", "SYST:DAT?") == ["9:11:05", "2021-9-8"]
    assert ask(peer, "SYST:TIM 24,0,0", "SYST:ERR?") == [None, "-222,Data out of range"]
    assert ask(peer, "SYST:PAS:STA?") == ["0"]
    ask(peer, "SYST:PAS DEFAULT,secret", "*SAV")
    assert ask(peer, "SYST:PAS:STA?", "SYST:ERR?") == ["1", "-221,Settings conflict"]    # *SAV needs it now
    ask(peer, "*PUD Battery Simulator", "SYST:FRO ON")
    assert ask(peer, "*PUD?", "SYST:FRO?", "SYST:FRO:STA?", "SYST:ERR?") == ["Battery Simulator", "1", "1", "0,None"]


def test_the_terminator_ends_the_replies(peer):
    ask(peer, "SYST:COMM:TER CRLF")
    assert peer.respond(b"SYST:COMM:TER?") == b"CRLF\r\n"
    ask(peer, "SYST:COMM:TER LF")
    assert peer.respond(b"OUTP?") == b"0\n"


def test_a_line_too_long_is_dropped_with_an_error(peer):
    """Over TCP: 8 MB without a terminator are not held (the peer keeps at most MAX_LINE bytes of a line), the
    terminator ends the dropped line with an error, and the next line is answered."""
    with peer:
        host, port = peer.url.removeprefix("socket://").rsplit(":", 1)
        with socket.create_connection((host, int(port)), timeout=5.0) as sock:
            chunk = b"X" * 65536
            for _ in range(128):
                sock.sendall(chunk)
            sock.sendall(b"\nSYST:ERR?\n")
            reply = sock.makefile("rb").readline()
    assert reply == b"-223,Too much data\n" and peer.MAX_LINE <= 4096
