"""The FW102C peer against the captured exchanges, byte for byte over its pty, and its model of the wheel.

Provenance (public sources): the exchanges `pos?\\r`→`pos?\\r3\\r> `, `pos=5\\r`→`pos=5\\r> `,
`pos=9\\r`→`pos=9\\rCommand error CMD_ARG_INVALID\\n\\r> `,
`*idn?\\r`→`*idn?\\rTHORLABS FW102C/FW212C Filter Wheel version 1.04\\r> ` and `speed?\\r`→`speed?\\r1\\r> ` as
github delmic/odemis src/odemis/driver/tlfw.py records them; the command set of the FW102C manual Rev H 2014
p. 11; the move timing (1 s per position at high speed, 2 s slow) of odemis.
"""

import pytest
import serial

from rig.config.rigfile import RigConfig
from rig.physics.brdf_models import get_model
from rig.simulators.faults import ATTENUATOR_FAULTS
from rig.simulators.fw102c_peer import FW102CPeer
from rig.simulators.world import SimWorld

CAPTURED = [(b"pos?\r", b"pos?\r3\r> "), (b"pos=5\r", b"pos=5\r> "),
            (b"pos=9\r", b"pos=9\rCommand error CMD_ARG_INVALID\n\r> "),
            (b"*idn?\r", b"*idn?\rTHORLABS FW102C/FW212C Filter Wheel version 1.04\r> "),
            (b"speed?\r", b"speed?\r1\r> ")]


@pytest.fixture
def world() -> SimWorld:
    return SimWorld(RigConfig(), get_model("lambert"), {"kd": 0.5})


@pytest.fixture
def peer(world) -> FW102CPeer:
    """At position 3 and high speed, as the unit of the captures was; not listening until `exchange` starts it."""
    p = FW102CPeer(world, position=3)
    p.speed = 1
    return p


@pytest.fixture
def exchange(peer):
    """`exchange(request) -> reply`: raw bytes to and from the peer over its pty, up to the prompt."""
    with peer, serial.Serial(peer.path, 115200, timeout=2) as port:
        def one(request: bytes) -> bytes:
            port.write(request)
            return port.read_until(b"> ")
        yield one


def answers(peer: FW102CPeer, *commands: str) -> list[bytes | None]:
    """What the peer sends back for each line (no pty)."""
    return [peer.respond(c.encode("ascii")) for c in commands]


def test_captured_exchanges_byte_for_byte(exchange, peer):
    for request, reply in CAPTURED:
        assert exchange(request) == reply
    assert peer.position == 5


def test_every_setting_reads_back(peer):
    assert answers(peer, "pcount?", "trig?", "sensors?", "speed=0", "speed?", "trig=1", "trig?", "sensors=0",
                   "sensors?") == [b"pcount?\r6\r> ", b"trig?\r0\r> ", b"sensors?\r1\r> ", b"speed=0\r> ",
                                   b"speed?\r0\r> ", b"trig=1\r> ", b"trig?\r1\r> ", b"sensors=0\r> ",
                                   b"sensors?\r0\r> "]
    assert answers(peer, "save") == [b"save\r> "]
    assert peer.saved == {"pos": 3, "pcount": 6, "speed": 0, "trig": 1, "sensors": 0, "baud": 1}


def test_the_baud_rate_setting_of_the_manual_is_kept_and_read_back(peer):
    """Manual Rev H p. 11: `baud=0` 9600, `baud=1` 115200, `baud?`; `save` stores it with the rest."""
    assert answers(peer, "baud?", "baud=0", "baud?", "save", "baud=1", "baud?") == [
        b"baud?\r1\r> ", b"baud=0\r> ", b"baud?\r0\r> ", b"save\r> ", b"baud=1\r> ", b"baud?\r1\r> "]
    assert peer.saved is not None and peer.saved["baud"] == 0


@pytest.mark.parametrize("command, error", [
    ("", "CMD_NOT_DEFINED"), ("Pos?", "CMD_NOT_DEFINED"), ("home", "CMD_NOT_DEFINED"), ("idn?", "CMD_NOT_DEFINED"),
    ("pos=0", "CMD_ARG_INVALID"), ("pos=7", "CMD_ARG_INVALID"), ("pos=", "CMD_ARG_INVALID"),
    ("pos=x", "CMD_ARG_INVALID"), ("speed=2", "CMD_ARG_INVALID"), ("pcount=8", "CMD_ARG_INVALID"),
    ("sensors=-1", "CMD_ARG_INVALID"), ("baud=2", "CMD_ARG_INVALID"), ("baud", "CMD_NOT_DEFINED")])
def test_errors(peer, command, error):
    assert answers(peer, command) == [command.encode() + b"\rCommand error " + error.encode() + b"\n\r> "]
    assert peer.position == 3 and peer.speed == 1


@pytest.mark.parametrize("speed, start, target, seconds", [
    (1, 3, 5, 2.0), (0, 3, 5, 4.0), (1, 1, 6, 1.0), (1, 2, 5, 3.0), (1, 4, 4, 0.0)])
def test_moves_take_rig_time_the_shorter_way_round(peer, world, speed, start, target, seconds):
    peer.speed, peer.position = speed, start
    t0 = world.clock.now()
    answers(peer, f"pos={target}")
    assert world.clock.now() - t0 == pytest.approx(seconds)
    assert peer.position == target


def test_a_twelve_position_wheel(world):
    peer = FW102CPeer(world, 12)
    assert answers(peer, "pcount?", "pos=7", "pos?") == [b"pcount?\r12\r> ", b"pos=7\r> ", b"pos?\r7\r> "]
    assert world.clock.now() == pytest.approx(6 * 2.0)         # slow at power-up
    assert answers(peer, "pcount=6", "pos?") == [b"pcount=6\r> ", b"pos?\r6\r> "]


def test_a_stuck_wheel_spends_the_time_without_turning(peer, world):
    peer.inject("stuck")
    assert answers(peer, "pos=3", "pos=5", "pos?") == [b"pos=3\r> ", b"pos=5\r> ", b"pos?\r3\r> "]
    assert world.clock.now() == pytest.approx(2.0)
    assert answers(peer, "pos=5") == [b"pos=5\r> "] and peer.position == 5


def test_reply_faults(peer):
    peer.inject("no_reply")
    peer.inject("garbled")
    assert answers(peer, "pos=5", "pos?", "pos?") == [None, bytes(b | 0x80 for b in b"pos?\r3\r") + b"> ",
                                                      b"pos?\r3\r> "]
    assert peer.position == 3                  # the lost line was not obeyed


@pytest.mark.parametrize("fault, count", [("short", 1), ("stuck", 0), ("overload", 1)])
def test_unknown_faults_are_refused(peer, fault, count):
    with pytest.raises(ValueError):
        peer.inject(fault, count)
    assert ATTENUATOR_FAULTS.names == ("no_reply", "garbled", "stuck")


@pytest.mark.parametrize("positions, position", [(8, 1), (6, 7), (6, 0)])
def test_impossible_wheels_are_refused(world, positions, position):
    with pytest.raises(ValueError):
        FW102CPeer(world, positions, position=position)
