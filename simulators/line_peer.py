"""The life cycle every line-protocol peer shares: listen, read lines, answer, inject faults, close.

A peer listens either on a free loopback TCP port (`socket://127.0.0.1:PORT`,
as an instrument's Ethernet module) or on a pseudo-terminal (`/dev/pts/N`,
which pyserial opens like any serial port), and answers each received line
from one server thread. Subclasses say what the instrument answers
(`respond`); injected reply faults spoil those answers the same way for
every peer. The servers never sleep: rig time passes only on the world's clock.

A received line is bounded: one longer than the peer's `MAX_LINE` is dropped as
it arrives (memory stays bounded whatever a client sends, and the cost is linear
in the bytes received) and answered at its terminator by `overlong`, the
instrument's own error behaviour (the default: no reply, the line is discarded).
"""

from __future__ import annotations

import os
import re
import select
import selectors
import socket
import threading
import tty
from collections import deque
from collections.abc import Callable
from typing import Any, Literal, Self

from rig.simulators.faults import PeerFaults

_QUICKACK = getattr(socket, "TCP_QUICKACK", None)       # Linux only

#: The bytes to send back for one received line (terminator stripped), or for None (a line too long);
#: None sends nothing.
Responder = Callable[[bytes | None], bytes | None]
#: A fresh splitter for one connection (each keeps its own unfinished line).
Splitters = Callable[[], "LineSplitter"]


class HangUp(Exception):
    """Raised by `respond` to drop the connection instead of answering."""


def peer_gone(conn: socket.socket) -> bool:
    """Whether the far end has closed `conn` (an EOF or a reset waits to be read), without consuming
    anything: a client that closed its socket, or died, before its server noticed."""
    try:
        return conn.recv(1, socket.MSG_PEEK | socket.MSG_DONTWAIT) == b""
    except (BlockingIOError, InterruptedError):
        return False                              # open, nothing to read
    except OSError:
        return True


class LineSplitter:
    """Cuts a byte stream into lines, holding at most `max_line` bytes of an unfinished one.

    `terminator`: each of its bytes ends a line. `b"\\n"`: LF, a CR before it dropped (CRLF taken too);
    `b"\\r"`: CR only; `b"\\r\\n"`: CR and/or LF in any combination, empty lines ignored (a device whose
    manual says so). A line longer than `max_line` is dropped while it arrives and reported as None at
    its terminator, so the instrument answers it where it would have answered the line."""

    def __init__(self, terminator: bytes, max_line: int):
        if terminator not in (b"\n", b"\r", b"\r\n"):
            raise ValueError(f"a line ends in LF, CR, or CR and/or LF, not {terminator!r}")
        self._ends = re.compile(b"[" + terminator + b"]")
        self._strip_cr = terminator == b"\n"
        self._skip_empty = terminator == b"\r\n"
        self._max = max_line
        self._held = bytearray()
        self._dropping = False            # inside a line already too long: its bytes are not kept

    def feed(self, data: bytes) -> list[bytes | None]:
        """The lines `data` completes (terminator stripped), None for each one too long."""
        lines: list[bytes | None] = []
        start = 0
        for end in self._ends.finditer(data):
            piece = data[start:end.start()]
            start = end.end()
            if self._dropping or len(self._held) + len(piece) > self._max:
                lines.append(None)
            else:
                line = bytes(self._held + piece)
                if self._strip_cr:
                    line = line.rstrip(b"\r")
                if line or not self._skip_empty:
                    lines.append(line)
            self._held.clear()
            self._dropping = False
        rest = data[start:]
        if self._dropping or len(self._held) + len(rest) > self._max:
            self._held.clear()
            self._dropping = True
        else:
            self._held += rest
        return lines


#: The longest a peer's stop waits for its serving thread (s). The thread is a daemon: one blocked in a reply to a
#: client that stopped reading (a pty's buffer full, a TCP window shut) must not keep `rig sim serve` from exiting
#: on SIGTERM.
STOP_JOIN_S = 5.0

class _TcpServer:
    """One thread serves the listener and every connection (clients may reconnect at will).

    `exclusive`: one connection at a time, as an instrument whose Ethernet module takes one client;
    a second one is closed at once, unless the held one turns out closed by its client (a driver
    that reconnects closes its old socket first; the server may not have seen that EOF yet)."""

    def __init__(self, respond: Responder, splitter: Splitters, name: str, exclusive: bool = False):
        self._respond = respond
        self._splitter = splitter
        self._exclusive = exclusive
        self._listener = socket.create_server(("127.0.0.1", 0))
        self._wake = socket.socketpair()
        self.address = f"socket://127.0.0.1:{self._listener.getsockname()[1]}"
        self._thread = threading.Thread(target=self._serve, name=f"{name} {self.address}", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._wake[1].send(b"x")
        self._thread.join(STOP_JOIN_S)      # bounded: a reply blocked on a client that stopped reading (daemon)
        for sock in (self._listener, *self._wake):
            sock.close()

    def _serve(self) -> None:
        sel = selectors.DefaultSelector()
        sel.register(self._listener, selectors.EVENT_READ)
        sel.register(self._wake[0], selectors.EVENT_READ)
        pending: dict[Any, LineSplitter] = {}
        try:
            while True:
                # The connections before the listener: a client that sent its last line and closed (one
                # connection per message) is read to its end before a new one is judged by `_free`.
                for key, _ in sorted(sel.select(), key=lambda ready: ready[0].fileobj is self._listener):
                    sock: Any = key.fileobj
                    if sock is self._wake[0]:
                        return
                    if sock is self._listener:
                        try:
                            conn, _ = self._listener.accept()
                        except OSError:               # the client gave up before we got to it
                            continue
                        if self._exclusive and not self._free(sel, pending):
                            conn.close()              # refused: nothing is sent
                            continue
                        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                        sel.register(conn, selectors.EVENT_READ)
                        pending[conn] = self._splitter()
                    elif not self._receive(sock, pending):
                        sel.unregister(sock)
                        del pending[sock]
                        sock.close()
        finally:
            for conn in pending:
                conn.close()
            sel.close()

    @staticmethod
    def _free(sel: selectors.BaseSelector, pending: dict[Any, Any]) -> bool:
        """Drop held connections whose client has gone; whether none is left."""
        for conn in [c for c in pending if peer_gone(c)]:
            sel.unregister(conn)
            del pending[conn]
            conn.close()
        return not pending

    def _receive(self, conn: socket.socket, pending: dict[Any, LineSplitter]) -> bool:
        """Answer the complete lines received; False when the connection is over."""
        try:
            data = conn.recv(4096)
        except OSError:
            return False
        if not data:
            return False
        # ACK at once: a setting has no reply to carry the ACK, and the driver's next line would
        # otherwise wait out Nagle + delayed ACK (~40 ms); Linux clears this flag after each use.
        if _QUICKACK is not None:
            conn.setsockopt(socket.IPPROTO_TCP, _QUICKACK, 1)
        try:
            for line in pending[conn].feed(data):
                reply = self._respond(line)
                if reply is not None:
                    conn.sendall(reply)
        except (HangUp, OSError):
            return False
        return True


class _PtyServer:
    """A reader thread on the master side of a pty; the slave fd stays open here, so the master
    never sees EIO between driver (re)connections. A pty has no modem lines: RTS/DTR ioctls fail
    on it, so the driver must not touch them."""

    def __init__(self, respond: Responder, splitter: Splitters, name: str):
        self._respond = respond
        self._splitter = splitter
        self._master, self._slave = os.openpty()
        tty.setraw(self._master)
        self._wake_r, self._wake_w = os.pipe()
        self.address = os.ttyname(self._slave)
        self._thread = threading.Thread(target=self._serve, name=f"{name} {self.address}", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        os.write(self._wake_w, b"x")
        self._thread.join(STOP_JOIN_S)      # bounded: a reply blocked on a full pty buffer nobody reads (daemon)
        for fd in (self._master, self._slave, self._wake_r, self._wake_w):
            os.close(fd)

    def _serve(self) -> None:
        lines = self._splitter()
        while True:
            ready, _, _ = select.select([self._master, self._wake_r], [], [])
            if self._wake_r in ready:
                return
            for line in lines.feed(os.read(self._master, 4096)):
                reply = self._respond(line)
                if reply is not None:
                    os.write(self._master, reply)


class LinePeer:
    """A line-oriented instrument on loopback TCP or a pty; subclasses answer (`respond`).

    `FAULTS` names what `inject` accepts; reply faults queue up and spoil the
    next replies the subclass hands to `wire`.
    """

    FAULTS: PeerFaults
    #: The part of a reply the `short` fault lets through (no terminator).
    SHORT_FRACTION = 0.5
    #: The longest line (bytes, terminator excluded) the instrument takes; a subclass lowers it to its manual's.
    #: The default bounds what a client can make the peer hold: no simulated instrument takes a longer line.
    MAX_LINE = 4096

    def __init__(self, medium: Literal["tcp", "pty"], *, exclusive: bool = False, terminator: bytes = b"\n"):
        """`exclusive` (TCP; read at `start`): refuse a second client while one is connected, so that two
        programs never interleave exchanges. A pty needs no flag: the driver opens it with an exclusive lock.
        `terminator`: what ends a received line, as the instrument's manual says (`LineSplitter`): LF (a CR
        before it dropped), CR (`b"\\r"`), or CR and/or LF (`b"\\r\\n"`)."""
        LineSplitter(terminator, self.MAX_LINE)                 # refuse a framing it cannot split at once
        self.medium = medium
        self.exclusive = exclusive
        self.terminator = terminator
        self.url: str | None = None
        self._server: _TcpServer | _PtyServer | None = None
        self._faults: deque[str] = deque()
        self._lock = threading.Lock()

    def respond(self, line: bytes) -> bytes | None:
        """Bytes to send back for one received line (terminator stripped); None sends nothing."""
        raise NotImplementedError

    def overlong(self) -> bytes | None:
        """The answer to a line longer than `MAX_LINE`, at its terminator; the default discards it unanswered."""
        return None

    def _answer(self, line: bytes | None) -> bytes | None:
        return self.overlong() if line is None else self.respond(line)

    def _splitter(self) -> LineSplitter:
        return LineSplitter(self.terminator, self.MAX_LINE)

    # -- lifecycle ----------------------------------------------------------------------------
    @property
    def path(self) -> str | None:
        """The address as a device path (a pty's `/dev/pts/N`)."""
        return self.url

    def start(self) -> str:
        """Listen and answer; returns the address for pyserial (`socket://127.0.0.1:PORT` or a pty path)."""
        if self._server is not None:
            raise RuntimeError(f"{type(self).__name__} already started on {self.url}")
        name = type(self).__name__
        self._server = (_TcpServer(self._answer, self._splitter, name, self.exclusive) if self.medium == "tcp"
                        else _PtyServer(self._answer, self._splitter, name))
        self.url = self._server.address
        return self.url

    def stop(self) -> None:
        """Close every connection and fd, join the server thread; safe to call twice."""
        if self._server is not None:
            self._server.stop()
            self._server = None

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- faults -------------------------------------------------------------------------------
    def inject(self, fault: str, count: int = 1) -> None:
        """Spoil the next `count` replies with `fault` (one of `FAULTS`)."""
        self.FAULTS.check(fault, count)
        with self._lock:
            self._faults.extend([fault] * count)

    def take_fault(self) -> str | None:
        """The fault for the reply being sent now, if one is pending."""
        with self._lock:
            return self._faults.popleft() if self._faults else None

    def wire(self, reply: str, fault: str | None) -> bytes | None:
        """The bytes that go on the wire for `reply`, as damaged by `fault`."""
        if fault == "disconnect":
            raise HangUp
        if fault == "no_reply":
            return None
        data = reply.encode("ascii")
        if fault == "garbled":                 # line noise: high bits set, terminator intact
            return bytes(b | 0x80 for b in data) + b"\n"
        if fault == "short":                   # cut off: part of the reply, no terminator
            return data[:max(int(len(data) * self.SHORT_FRACTION), 1)]
        return data + b"\n"
