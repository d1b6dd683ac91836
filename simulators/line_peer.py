"""The life cycle every line-protocol peer shares: listen, read lines, answer, inject faults, close.

A peer listens either on a free loopback TCP port (`socket://127.0.0.1:PORT`,
as an instrument's Ethernet module) or on a pseudo-terminal (`/dev/pts/N`,
which pyserial opens like any serial port), and answers each received line
from one server thread. Subclasses say what the instrument answers
(`respond`); injected reply faults spoil those answers the same way for
every peer. The servers never sleep: rig time passes only on the world's clock.
"""

from __future__ import annotations

import os
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

#: `respond(line)`: the bytes to send back for one received line (terminator stripped); None sends nothing.
Responder = Callable[[bytes], bytes | None]


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


class _TcpServer:
    """One thread serves the listener and every connection (clients may reconnect at will).

    `exclusive`: one connection at a time, as an instrument whose Ethernet module takes one client;
    a second one is closed at once, unless the held one turns out closed by its client (a driver
    that reconnects closes its old socket first; the server may not have seen that EOF yet)."""

    def __init__(self, respond: Responder, name: str, exclusive: bool = False):
        self._respond = respond
        self._exclusive = exclusive
        self._listener = socket.create_server(("127.0.0.1", 0))
        self._wake = socket.socketpair()
        self.address = f"socket://127.0.0.1:{self._listener.getsockname()[1]}"
        self._thread = threading.Thread(target=self._serve, name=f"{name} {self.address}", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._wake[1].send(b"x")
        self._thread.join()
        for sock in (self._listener, *self._wake):
            sock.close()

    def _serve(self) -> None:
        sel = selectors.DefaultSelector()
        sel.register(self._listener, selectors.EVENT_READ)
        sel.register(self._wake[0], selectors.EVENT_READ)
        pending: dict[Any, bytes] = {}
        try:
            while True:
                for key, _ in sel.select():
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
                        pending[conn] = b""
                    elif not self._receive(sock, pending):
                        sel.unregister(sock)
                        del pending[sock]
                        sock.close()
        finally:
            for conn in pending:
                conn.close()
            sel.close()

    @staticmethod
    def _free(sel: selectors.BaseSelector, pending: dict[Any, bytes]) -> bool:
        """Drop held connections whose client has gone; whether none is left."""
        for conn in [c for c in pending if peer_gone(c)]:
            sel.unregister(conn)
            del pending[conn]
            conn.close()
        return not pending

    def _receive(self, conn: socket.socket, pending: dict[Any, bytes]) -> bool:
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
        *lines, pending[conn] = (pending[conn] + data).split(b"\n")
        try:
            for line in lines:
                reply = self._respond(line.rstrip(b"\r"))
                if reply is not None:
                    conn.sendall(reply)
        except (HangUp, OSError):
            return False
        return True


class _PtyServer:
    """A reader thread on the master side of a pty; the slave fd stays open here, so the master
    never sees EIO between driver (re)connections. A pty has no modem lines: RTS/DTR ioctls fail
    on it, so the driver must not touch them."""

    def __init__(self, respond: Responder, name: str, terminator: bytes = b"\n"):
        self._respond = respond
        self._terminator = terminator
        self._master, self._slave = os.openpty()
        tty.setraw(self._master)
        self._wake_r, self._wake_w = os.pipe()
        self.address = os.ttyname(self._slave)
        self._thread = threading.Thread(target=self._serve, name=f"{name} {self.address}", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        os.write(self._wake_w, b"x")
        self._thread.join()
        for fd in (self._master, self._slave, self._wake_r, self._wake_w):
            os.close(fd)

    def _serve(self) -> None:
        pending = b""
        while True:
            ready, _, _ = select.select([self._master, self._wake_r], [], [])
            if self._wake_r in ready:
                return
            pending += os.read(self._master, 4096)
            *lines, pending = pending.split(self._terminator)
            for line in lines:
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

    def __init__(self, medium: Literal["tcp", "pty"], *, exclusive: bool = False, terminator: bytes = b"\n"):
        """`exclusive` (TCP; read at `start`): refuse a second client while one is connected, so that two
        programs never interleave exchanges. A pty needs no flag: the driver opens it with an exclusive lock.
        `terminator` (pty): what ends a received line (a CR for an instrument that takes CR-terminated lines)."""
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
        self._server = (_TcpServer(self.respond, name, self.exclusive) if self.medium == "tcp"
                        else _PtyServer(self.respond, name, self.terminator))
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
