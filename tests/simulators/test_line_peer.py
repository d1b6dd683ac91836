"""LinePeer over TCP: one client at a time when exclusive, and a reconnecting client always gets through; a
received line is bounded in length and framed as the instrument's manual says."""

import os
import select
import selectors
import socket
import struct
import threading
import tracemalloc
from collections.abc import Callable

import pytest
import serial

from rig.config.rigfile import RigConfig
from rig.drivers.transport import LineTransport
from rig.physics.brdf_models import get_model
from rig.simulators.delta_sm_peer import DeltaSMPeer
from rig.simulators.faults import PeerFaults
from rig.simulators.line_peer import LinePeer, LineSplitter, _TcpServer, peer_gone
from rig.simulators.p9710_peer import P9710Peer
from rig.simulators.world import SimWorld
from rig.simulators.zaber_peer import ZaberPeer


class EchoPeer(LinePeer):
    """Answers every line in upper case; `disconnect` hangs up instead."""

    FAULTS = PeerFaults(("disconnect",))
    def respond(self, line: bytes) -> bytes | None:
        return self.wire(line.decode("ascii").upper(), self.take_fault())


def connect(url: str) -> socket.socket:
    host, port = url.removeprefix("socket://").split(":")
    return socket.create_connection((host, int(port)), timeout=2.0)


def ask(sock: socket.socket, line: bytes) -> bytes:
    """Send one line; what arrives before the reply's LF (b"" if the peer closed the connection)."""
    sock.sendall(line + b"\n")
    reply = b""
    while not reply.endswith(b"\n"):
        try:
            chunk = sock.recv(64)
        except ConnectionResetError:
            chunk = b""
        if not chunk:
            return reply
        reply += chunk
    return reply


def refused(sock: socket.socket) -> bool:
    """Whether the peer closed this connection without a word."""
    try:
        return sock.recv(64) == b""
    except ConnectionResetError:
        return True


def test_connections_are_shared_by_default():
    with EchoPeer("tcp") as peer:
        assert peer.url is not None
        with connect(peer.url) as first, connect(peer.url) as second:
            assert ask(first, b"one") == b"ONE\n"
            assert ask(second, b"two") == b"TWO\n"
            assert ask(first, b"three") == b"THREE\n"


def test_exclusive_peer_closes_a_second_connection_and_keeps_the_first():
    with EchoPeer("tcp", exclusive=True) as peer:
        assert peer.url is not None
        with connect(peer.url) as first:
            assert ask(first, b"mine") == b"MINE\n"
            with connect(peer.url) as second:
                assert refused(second)
            assert ask(first, b"still mine") == b"STILL MINE\n"


def test_exclusive_can_be_set_before_start():
    peer = EchoPeer("tcp")
    peer.exclusive = True              # a peer class whose constructor does not take the flag
    with peer:
        assert peer.url is not None
        with connect(peer.url) as first, connect(peer.url) as second:
            assert ask(first, b"a") == b"A\n"
            assert refused(second)


@pytest.mark.parametrize("abrupt", [False, True], ids=["close", "reset"])
def test_a_client_that_closes_and_reconnects_at_once_gets_through(abrupt):
    """Close (FIN) or reset (RST, as a killed client's socket may end) and reconnect straight away, many
    times: whether the server sees the old connection end before or after the new one arrives, it lets
    the new one in."""
    with EchoPeer("tcp", exclusive=True) as peer:
        assert peer.url is not None
        for i in range(30):
            sock = connect(peer.url)
            assert ask(sock, b"n%d" % i) == b"N%d\n" % i
            if abrupt:
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
            sock.close()


def test_an_accept_drops_a_held_connection_whose_client_has_gone_and_keeps_a_live_one():
    """The check an exclusive server makes before refusing, on its own: which of an old connection's end
    and a new connection the server meets first is up to the kernel's event order, which the tests
    above cannot force."""
    listener = socket.create_server(("127.0.0.1", 0))
    sel = selectors.DefaultSelector()
    with listener, sel, socket.create_connection(listener.getsockname()) as live, \
            socket.create_connection(listener.getsockname()) as leaving:
        held = {listener.accept()[0]: b"", listener.accept()[0]: b""}
        for conn in held:
            sel.register(conn, selectors.EVENT_READ)
        assert not _TcpServer._free(sel, held) and len(held) == 2
        leaving.close()
        assert not _TcpServer._free(sel, held) and len(held) == 1
        live.close()
        assert _TcpServer._free(sel, held) and not held and not sel.get_map()


def test_the_line_transport_reconnects_to_an_exclusive_peer_after_a_dropped_link():
    with EchoPeer("tcp", exclusive=True) as peer:
        assert peer.url is not None
        link = LineTransport("echo", peer.url, timeout_s=2.0)
        try:
            assert link.query("before") == "BEFORE"
            link.reconnect()                                   # what a retry does after a fault
            assert link.query("after") == "AFTER"
            peer.inject("disconnect")                          # the peer hangs up on the next line
            with pytest.raises(Exception, match="echo"):
                link.query("dropped")
            link.reconnect()
            assert link.query("again") == "AGAIN"
        finally:
            link.close()


def test_peer_gone_tells_a_closed_connection_from_an_open_one():
    listener = socket.create_server(("127.0.0.1", 0))
    with listener, socket.create_connection(listener.getsockname()) as client:
        server_side, _ = listener.accept()
        with server_side:
            assert not peer_gone(server_side)                  # open, nothing to read
            client.sendall(b"pending")
            assert select.select([server_side], [], [], 2.0)[0]
            assert not peer_gone(server_side)                  # data waiting: alive
            assert server_side.recv(64) == b"pending"          # peeking consumed nothing
            client.close()                                     # on loopback the FIN is there on return
            assert peer_gone(server_side)


def _peers() -> list[tuple[str, Callable[[], LinePeer]]]:
    world = lambda: SimWorld(RigConfig(), get_model("lambert"), {"kd": 0.5})    # noqa: E731
    arm = RigConfig().axes
    return [("p9710", lambda: P9710Peer(world())), ("delta-sm", lambda: DeltaSMPeer(world())),
            ("zaber", lambda: ZaberPeer(world(), [(1, 1, "arm_azimuth", arm.arm_azimuth)]))]


@pytest.mark.parametrize("make", [make for _, make in _peers()], ids=[name for name, _ in _peers()])
def test_every_line_peer_starts_once_stops_twice_and_refuses_unknown_faults(make):
    """The life cycle every peer inherits from LinePeer; nothing is left open."""
    fds, threads = set(os.listdir("/proc/self/fd")), set(threading.enumerate())
    peer = make()
    peer.start()
    with pytest.raises(RuntimeError, match="already started"):
        peer.start()
    peer.stop()
    peer.stop()
    with pytest.raises(ValueError, match="unknown fault 'smoke'"):
        peer.inject("smoke")
    assert set(os.listdir("/proc/self/fd")) == fds and set(threading.enumerate()) == threads


# -- framing and the line-length bound ---------------------------------------------------------------
class ShortLinePeer(EchoPeer):
    """Takes lines of up to 16 bytes; a longer one is answered `TOO LONG` (an instrument's error reply)."""

    MAX_LINE = 16

    def overlong(self) -> bytes | None:
        return b"TOO LONG\n"


@pytest.mark.parametrize("terminator, data, lines", [
    (b"\n", b"a\r\nb\n\nc\rd\ne", [b"a", b"b", b"", b"c\rd"]),          # LF; a CR before it dropped
    (b"\r", b"a\rb\nc\r\r", [b"a", b"b\nc", b""]),                      # CR only
    (b"\r\n", b"a\rb\nc\r\n\n\rd\n\re", [b"a", b"b", b"c", b"d"]),      # CR and/or LF, empty lines ignored
], ids=["LF", "CR", "CR-and-or-LF"])
def test_the_splitter_frames_lines_as_told(terminator, data, lines):
    splitter = LineSplitter(terminator, 16)
    assert [line for i in range(len(data)) for line in splitter.feed(data[i:i + 1])] == lines   # byte by byte
    assert LineSplitter(terminator, 16).feed(data) == lines                                      # at once


def test_the_splitter_reports_an_overlong_line_at_its_end_and_keeps_the_next():
    splitter = LineSplitter(b"\n", 4)
    assert splitter.feed(b"abcd") == [] and splitter.feed(b"e") == []
    assert splitter.feed(b"fgh\nok\n12345\nabcd\n") == [None, b"ok", None, b"abcd"]
    with pytest.raises(ValueError, match="a line ends in LF, CR, or CR and/or LF, not b';'"):
        LineSplitter(b";", 4)


@pytest.mark.parametrize("medium", ["tcp", "pty"])
def test_an_endless_line_is_dropped_as_it_arrives_and_answered_as_the_instrument_does(medium):
    """8 MB without a terminator (before: all of it held, and copied once per 4 kB received, in a peer made
    to answer it) costs the peer at most a line's worth of memory; the line is answered with the peer's error
    reply, and the next line as usual."""
    chunk, chunks = b"x" * (1 << 18), 32
    with ShortLinePeer(medium) as peer:
        assert peer.url is not None
        tracemalloc.start()
        try:
            if medium == "tcp":
                with connect(peer.url) as sock, sock.makefile("rb") as replies:
                    for _ in range(chunks):
                        sock.sendall(chunk)
                    sock.sendall(b"\nnext\n")
                    assert [replies.readline(), replies.readline()] == [b"TOO LONG\n", b"NEXT\n"]
            else:
                with serial.Serial(peer.url, timeout=5.0) as port:
                    for _ in range(chunks):
                        port.write(chunk)
                    port.write(b"\nnext\n")
                    assert port.read_until(b"\n") == b"TOO LONG\n" and port.read_until(b"\n") == b"NEXT\n"
            peak = tracemalloc.get_traced_memory()[1]
        finally:
            tracemalloc.stop()
    assert peak < 4 * len(chunk)          # the client's own chunk and its copies; never the 8 MB line
