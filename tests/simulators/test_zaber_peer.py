"""The Zaber chain peer byte for byte: what zaber-motion and a lab's terminal send besides our driver's commands.

Provenance: the Zaber ASCII protocol manual (zaber.com/wiki/Manuals/ASCII_Protocol_Manual: a command ends in
"any combination of CR and/or LF", replies end in CRLF, `#` info lines follow some replies; `move rel|vel`,
`estop`, `tools echo`, the settings `pos`, `encoder.pos`, `deviceid`, `system.serial`, `comm.packet.size.max`,
`DEVICEONLY`), and the requests zaber-motion 10.3 sent to this peer (`/0 0 00:00`, `/1 0 01 get
comm.packet.size.max:CF`, … captured in tests/vendors/test_vendor_zaber.py). The values of `deviceid`,
`system.serial`, the packet size and the `help` text are the peer's own (simulators/zaber_peer.py).
"""

import socket
from collections.abc import Iterator

import pytest
import serial

from rig.config.rigfile import AxisConfig, RigConfig, SimulationConfig
from rig.physics.brdf_models import get_model
from rig.simulators.world import SimWorld
from rig.simulators.zaber_peer import CYCLE_DIST, DEVICE_ID, PACKET_SIZE_MAX, SERIAL_BASE, ZaberPeer, lrc

AXIS = AxisConfig(limits_deg=(-90, 90), speed_deg_s=15, accel_deg_s2=30, settle_s=0.2)
LIMIT = CYCLE_DIST // 4                     # 90° in µsteps
#: 0.001° (half the default 0.002° backlash) in µsteps, rounded: the encoder lags the last travel by this.
LAG = round(0.001 * CYCLE_DIST / 360)


class Chain:
    """Two single-axis devices, homed, over TCP (or a pty): `ask(request, lines)` returns the reply lines."""

    def __init__(self, medium: str):
        self.world = SimWorld(RigConfig(simulation=SimulationConfig(positioning_sigma_deg=0.0,
                                                                    axis_zero_sigma_deg=0.0)),
                              get_model("lambert"), {"kd": 0.5})
        self.peer = ZaberPeer(self.world, [(1, 1, "x", AXIS), (2, 1, "y", AXIS)], medium=medium,  # type: ignore
                              homed=True)
        self.medium = medium

    def __enter__(self) -> "Chain":
        url = self.peer.start()
        if self.medium == "tcp":
            host, port = url.removeprefix("socket://").split(":")
            self._sock = socket.create_connection((host, int(port)), timeout=1.0)
            self._read = self._sock.makefile("rb")
            self._write = self._sock.sendall
        else:
            self._port = serial.Serial(url, 115200, timeout=1.0)
            self._read, self._write = self._port, self._port.write
        return self

    def __exit__(self, *exc: object) -> None:
        if self.medium == "tcp":
            self._read.close()
            self._sock.close()
        else:
            self._port.close()
        self.peer.stop()

    def ask(self, request: bytes, lines: int = 1) -> list[bytes]:
        self._write(request)
        return [self._read.readline() for _ in range(lines)]

    def settle(self, seconds: float = 30.0) -> None:
        self.world.clock.sleep(seconds)


@pytest.fixture(params=["tcp", "pty"])
def chain(request) -> Iterator[Chain]:
    with Chain(request.param) as c:
        yield c


@pytest.fixture
def tcp() -> Iterator[Chain]:
    with Chain("tcp") as c:
        yield c


@pytest.mark.parametrize("end", [b"\r", b"\n", b"\r\n", b"\n\r", b"\r\r\n"], ids=["CR", "LF", "CRLF", "LFCR", "CRCRLF"])
def test_a_command_ends_in_cr_and_or_lf_and_is_answered_once(chain, end):
    assert chain.ask(b"/1 1 get pos" + end + b"/2 1 get pos\n", lines=2) == [b"@01 1 OK IDLE -- 0\r\n",
                                                                         b"@02 1 OK IDLE -- 0\r\n"]


def test_the_identification_zaber_motion_reads(tcp):
    """Device-scope settings at axis 0; through an axis they are refused as the manual says (DEVICEONLY)."""
    assert tcp.ask(b"/1 0 get deviceid\n") == [f"@01 0 OK IDLE -- {DEVICE_ID}\r\n".encode()]
    assert tcp.ask(b"/2 0 get system.serial\n") == [f"@02 0 OK IDLE -- {SERIAL_BASE + 2}\r\n".encode()]
    assert tcp.ask(b"/1 0 01 get comm.packet.size.max:CF\n") == [
        f"@01 0 01 OK IDLE -- {PACKET_SIZE_MAX}:{lrc(f'01 0 01 OK IDLE -- {PACKET_SIZE_MAX}')}\r\n".encode()]
    assert tcp.ask(b"/0 0 00:00\n", lines=2) == [f"@0{d} 0 00 OK IDLE -- 0:{lrc(f'0{d} 0 00 OK IDLE -- 0')}\r\n"
                                                 .encode() for d in (1, 2)]
    assert tcp.ask(b"/1 1 get deviceid\n") == [b"@01 1 RJ IDLE -- DEVICEONLY\r\n"]


def test_get_pos_after_a_move_is_the_target_exactly_and_the_encoder_lags_by_the_backlash(chain):
    assert chain.ask(b"/1 1 move abs 100000\n") == [b"@01 1 OK BUSY -- 0\r\n"]
    chain.settle()
    assert chain.ask(b"/1 1 get pos\n") == [b"@01 1 OK IDLE -- 100000\r\n"]
    assert chain.ask(b"/1 1 get encoder.pos\n") == [f"@01 1 OK IDLE -- {100000 - LAG}\r\n".encode()]


def test_move_rel_is_relative_to_the_present_position_and_bounded_by_the_limits(tcp):
    tcp.ask(b"/1 1 move abs 10000\n")
    tcp.settle()
    assert tcp.ask(b"/1 1 move rel -2500\n") == [b"@01 1 OK BUSY -- 0\r\n"]
    tcp.settle()
    assert tcp.ask(b"/1 1 get pos\n") == [b"@01 1 OK IDLE -- 7500\r\n"]
    assert tcp.ask(f"/1 1 move rel {LIMIT}\n".encode()) == [b"@01 1 RJ IDLE -- BADDATA\r\n"]
    assert tcp.ask(b"/1 1 get limit.max\n") == [f"@01 1 OK IDLE -- {LIMIT}\r\n".encode()]


def test_move_vel_runs_until_stopped_or_at_the_limit(tcp):
    assert tcp.ask(b"/1 1 move vel 20000\n") == [b"@01 1 OK BUSY -- 0\r\n"]
    tcp.settle(1.0)
    moving = int(tcp.ask(b"/1 1 get pos\n")[0].split()[-1])
    assert 0 < moving < LIMIT
    assert tcp.ask(b"/1 1 stop\n") == [b"@01 1 OK BUSY -- 0\r\n"]
    tcp.settle(1.0)
    assert tcp.ask(b"/1 1 get pos\n") == [f"@01 1 OK IDLE -- {moving}\r\n".encode()]    # stop halts at once
    assert tcp.ask(b"/2 1 move vel -104858\n") == [b"@02 1 OK BUSY -- 0\r\n"]
    tcp.settle(60.0)
    assert tcp.ask(b"/2 1 get pos\n") == [f"@02 1 OK IDLE -- {-LIMIT}\r\n".encode()]
    assert tcp.ask(b"/2 1 move vel ten\n") == [b"@02 1 RJ IDLE -- BADDATA\r\n"]


def test_estop_halts_a_move(tcp):
    tcp.ask(b"/1 1 move abs 300000\n")
    tcp.settle(1.0)
    assert tcp.ask(b"/1 1 estop\n") == [b"@01 1 OK BUSY -- 0\r\n"]
    tcp.settle(1.0)
    assert 0 < int(tcp.ask(b"/1 1 get pos\n")[0].split()[-1]) < 300000


def test_tools_echo_answers_its_text(tcp):
    assert tcp.ask(b"/1 tools echo hello world\n") == [b"@01 0 OK IDLE -- hello world\r\n"]
    assert tcp.ask(b"/1 0 14 tools echo hello:B6\n") == [b"@01 0 14 OK IDLE -- hello:" +
                                                          lrc("01 0 14 OK IDLE -- hello").encode() + b"\r\n"]


def test_help_answers_then_sends_info_lines(tcp):
    reply, first = tcp.ask(b"/1 help\n", lines=2)
    assert reply == b"@01 0 OK IDLE -- 0\r\n" and first == b"#01 0 home\r\n"


def test_a_command_longer_than_the_packet_size_is_discarded_and_the_next_one_answered(chain):
    long = b"/1 1 tools echo " + b"x" * PACKET_SIZE_MAX + b"\n"
    assert chain.ask(long + b"/1 1 get pos\n") == [b"@01 1 OK IDLE -- 0\r\n"]
