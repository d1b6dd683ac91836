"""The simulated camera served on loopback TCP: protocol `rig-sim-camera/1` (docs/sim-camera-protocol.md).

A real luminance camera has no public wire protocol, so `rig sim serve` puts the simulated
camera behind this small one of ours. Exposing is split in two requests: EXPOSE renders at
once and answers the rig time the exposure takes; the client sleeps that time on its own
clock (its lamp keep-alive runs meanwhile) and then READs the frame. A blocking exposure of
up to 15 s would starve the lamp's communication watchdog.

One connection at a time holds the session (from HELLO until BYE or its socket closes); any
other is told `ERR busy` and closed, so a second client can never interleave with a campaign.
Each connection is served by its own thread; the session's requests are handled one by one.
"""

from __future__ import annotations

import json
import socket
import threading
import time
from dataclasses import fields
from typing import Self

import numpy as np

from rig.core.errors import DeviceError
from rig.core.values import Frame, SensorInfo, Window
from rig.simulators.camera import SimCamera
from rig.simulators.clock import SimClock
from rig.simulators.line_peer import peer_gone
from rig.simulators.world import SimWorld

PROTOCOL = "rig-sim-camera/1"
#: Wall time between two looks at the world clock while a READ waits for its frame's ready time.
POLL_S = 0.005


class ProtocolError(Exception):
    """A request the server answers with `ERR <message>`."""


class _Session:
    """The connection that holds the camera, since when, and the frame it exposed (with its ready time)."""

    def __init__(self, conn: socket.socket, peer: str, rig_time_s: float):
        self.conn = conn
        self.peer = peer
        self.since = f"rig time {rig_time_s:.3f} s (wall {time.strftime('%Y-%m-%d %H:%M:%S')})"
        self.frame: tuple[Frame, float] | None = None


def _shutdown(conn: socket.socket) -> None:
    """End a connection from another thread: its thread's recv (or sendall) returns, and it closes it."""
    try:
        conn.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass                                            # already gone


class CameraServer:
    """The simulated camera of `world` on a free loopback port; `start()` returns its address."""

    def __init__(self, world: SimWorld):
        self.world = world
        self.camera = SimCamera(world)
        self.url: str | None = None
        self._listener: socket.socket | None = None
        self._accepting: threading.Thread | None = None
        self._threads: dict[socket.socket, threading.Thread] = {}
        self._session: _Session | None = None
        self._lock = threading.Lock()
        self._stopping = threading.Event()

    # -- lifecycle ----------------------------------------------------------------------------
    def start(self, port: int = 0) -> str:
        """Listen on 127.0.0.1:`port` (0: a free one) and serve; returns `socket://127.0.0.1:PORT`."""
        if self._listener is not None:
            raise RuntimeError(f"CameraServer already started on {self.url}")
        self._stopping.clear()
        self._listener = socket.create_server(("127.0.0.1", port))
        self.url = f"socket://127.0.0.1:{self._listener.getsockname()[1]}"
        self._accepting = threading.Thread(target=self._accept, name=f"CameraServer {self.url}", daemon=True)
        self._accepting.start()
        return self.url

    def stop(self) -> None:
        """Close every connection and the listener, join every thread; safe to call twice."""
        listener, accepting = self._listener, self._accepting
        if listener is None or accepting is None:
            return
        with self._lock:
            self._stopping.set()
            threads = list(self._threads.items())
        for conn, _ in threads:
            _shutdown(conn)
        try:                                        # wake accept() portably: connect once
            socket.create_connection(listener.getsockname(), timeout=1.0).close()
        except OSError:
            pass
        accepting.join()
        for _, thread in threads:
            thread.join()
        listener.close()
        self._listener = self._accepting = None

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()

    # -- connections --------------------------------------------------------------------------
    def _accept(self) -> None:
        assert self._listener is not None
        while True:
            try:
                conn, (host, port) = self._listener.accept()
            except OSError:
                return
            with self._lock:
                if self._stopping.is_set():
                    conn.close()
                    return
                conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                thread = threading.Thread(target=self._serve, args=(conn, f"{host}:{port}"),
                                          name=f"CameraServer client {host}:{port}", daemon=True)
                self._threads[conn] = thread
                thread.start()

    def _serve(self, conn: socket.socket, peer: str) -> None:
        """Answer one connection's lines until it closes, says BYE or is refused."""
        try:
            with conn.makefile("rb") as lines:
                for raw in lines:
                    if not raw.endswith(b"\n"):
                        break                               # the connection closed mid-line
                    reply, close = self._answer(conn, peer, raw.rstrip(b"\r\n"))
                    conn.sendall(reply)
                    if close:
                        break
        except OSError:
            pass                                            # the client went away, or stop()
        finally:
            with self._lock:
                if self._session is not None and self._session.conn is conn:
                    self._session = None
                self._threads.pop(conn, None)
            conn.close()

    def _answer(self, conn: socket.socket, peer: str, line: bytes) -> tuple[bytes, bool]:
        """The reply bytes for one request line, and whether to close the connection after it."""
        try:
            text = line.decode("ascii")
        except UnicodeDecodeError:
            text = None
        session = self._claim(conn, peer, text)
        if isinstance(session, bytes):
            return session, True
        if session is None:                                 # free camera, request other than HELLO
            return _err(f"no session: send 'HELLO {PROTOCOL}' first"), False
        try:
            if text is None:
                raise ProtocolError(f"request {line!r} is not ASCII")
            verb, *args = text.split()
            if verb == "HELLO":
                return _ok(f"{PROTOCOL} {self.camera.identity()}"), False
            if verb == "BYE":
                with self._lock:
                    self._session = None
                return _ok(""), True
            if verb == "SENSOR?":
                # SensorInfo's own fields (a calibration file's coefficient included; its flat field is not sent)
                return _ok(json.dumps({f.name: getattr(self.camera.sensor, f.name) for f in fields(SensorInfo)})), False
            if verb == "EXPOSE":
                return _ok(repr(self._expose(session, args))), False
            if verb == "READ":
                return self._read(session), False
            if verb == "SCENE":
                self.camera.show(text.split(None, 1)[1] if args else "")
                return _ok(""), False
            raise ProtocolError(f"unknown request {text!r}")
        except ValueError:
            return _err(f"malformed request {text!r}"), False
        except (ProtocolError, DeviceError) as exc:
            return _err(str(exc).removeprefix("camera: ")), False

    def _claim(self, conn: socket.socket, peer: str, text: str | None) -> _Session | bytes | None:
        """The session this connection holds, taking it on HELLO if it is free; the refusal (bytes,
        then close) for a connection the camera is busy for or that speaks another protocol."""
        with self._lock:
            held = self._session
            if held is not None and held.conn is not conn and peer_gone(held.conn):
                _shutdown(held.conn)                        # its thread ends and forgets it
                held = self._session = None
            if held is not None and held.conn is conn:
                return held
            if held is not None:
                return _err(f"busy: the simulated camera is held by {held.peer} since {held.since}")
            if text is None or text.split()[:1] != ["HELLO"]:
                return None
            if text.split()[1:] != [PROTOCOL]:
                return _err(f"unsupported protocol {text[5:].strip()!r}: this server speaks {PROTOCOL}")
            self._session = _Session(conn, peer, self.world.clock.now())
            return self._session

    # -- exposing -------------------------------------------------------------------------------
    def _expose(self, session: _Session, args: list[str]) -> float:
        """`EXPOSE <exposure_s> <dark 0|1> <x0> <y0> <width> <height>`: render now, keep the frame."""
        if len(args) != 6 or args[1] not in ("0", "1"):
            raise ValueError("EXPOSE takes <exposure_s> <dark 0|1> <x0> <y0> <width> <height>")
        exposure_s = float(args[0])
        x0, y0, width, height = (int(a) for a in args[2:])
        if width <= 0 or height <= 0:
            raise ProtocolError(f"window {width}x{height} px is empty")
        session.frame = None
        frame, duration = self.camera.render(exposure_s, Window(x0, y0, width, height), dark=args[1] == "1")
        session.frame = frame, frame.meta["start_s"] + duration
        return duration

    def _read(self, session: _Session) -> bytes:
        """The pending frame, once the world clock reaches its ready time (a SimClock is not waited on:
        the client's own sleep advanced it). A holder found gone meanwhile (`_claim`) ends the wait."""
        if session.frame is None:
            raise ProtocolError("READ without an exposure: send EXPOSE first")
        (frame, ready), session.frame = session.frame, None
        clock = self.world.clock
        if not isinstance(clock, SimClock):                 # until ready, stopped, or the client gone
            while clock.now() < ready and self._session is session and not self._stopping.wait(POLL_S):
                pass
        pixels = np.ascontiguousarray(frame.pixels_dn, dtype="<u2").tobytes()
        w = frame.window
        header = (f"OK FRAME {w.width} {w.height} {frame.exposure_s!r} {frame.meta['start_s']!r} "
                  f"{int(frame.dark)} {len(pixels)}\n")
        return header.encode("ascii") + pixels


def _ok(text: str) -> bytes:
    return (f"OK {text}".rstrip() + "\n").encode("ascii")


def _err(message: str) -> bytes:
    return f"ERR {message}\n".encode("ascii", "backslashreplace")
