"""Client of a served simulated camera (`rig sim serve`), protocol `rig-sim-camera/1`.

See docs/sim-camera-protocol.md. The exposure time is slept on the client's clock between
EXPOSE and READ, so the lamp's keep-alive runs during long exposures exactly as with a
vendor camera whose SDK returns while the shutter is open.
"""

from __future__ import annotations

import json
import math
import socket
from io import BufferedReader
from typing import Any

import numpy as np

from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.core.values import Frame, SensorInfo, Window
from rig.drivers.interfaces import LuminanceCamera

PROTOCOL = "rig-sim-camera/1"


def parse_address(address: str) -> tuple[str, int]:
    """(host, port) of `socket://host:port`; ValueError naming the address otherwise."""
    host, sep, port = address.removeprefix("socket://").rpartition(":")
    if not address.startswith("socket://") or not sep or not host or not port.isdigit():
        raise ValueError(f"camera address {address!r} is not socket://host:port")
    return host, int(port)


class ServedCamera(LuminanceCamera):
    """The simulated camera of a served rig, over loopback TCP; one session from connect to close."""

    def __init__(self, address: str, *, clock: Clock, timeout_s: float = 5.0, name: str = "camera"):
        self.address = address
        self.clock = clock
        self.timeout_s = timeout_s
        self.name = name
        try:
            host, port = parse_address(address)
        except ValueError as exc:
            raise DeviceError(name, str(exc)) from None
        self._address = host, port
        self._sock: socket.socket | None = None
        self._stream: BufferedReader | None = None
        self._closed = False
        self._connect()

    @classmethod
    def from_rig(cls, *, clock: Clock, settings: Any, address: str) -> ServedCamera:
        """The rig-file contract (rig.drivers.registry): the sensor comes from the server, not `settings`."""
        return cls(address, clock=clock)

    def identity(self) -> str:
        return self._identity

    def capture(self, exposure_s: float, window: Window | None = None) -> Frame:
        return self._expose(exposure_s, window, dark=False)

    def capture_dark(self, exposure_s: float, window: Window | None = None) -> Frame:
        return self._expose(exposure_s, window, dark=True)

    def show(self, scene: str) -> None:
        """Put `scene` before the simulated camera (`SCENE`: the sample, the empty holder with the lamp's exit, or a
        ChArUco board), as an operator does for `rig calibrate geometry`."""
        self._request(f"SCENE {scene}")

    def close(self) -> None:
        """Say BYE (best effort) and close the connection; safe to call twice."""
        self._closed = True
        if self._sock is None:
            return
        try:
            self._exchange("BYE")
        except DeviceError:
            pass
        self._drop()

    def _connect(self) -> None:
        """Open the session: connect, HELLO, SENSOR? (sets `sensor`)."""
        try:
            sock = socket.create_connection(self._address, timeout=self.timeout_s)
        except OSError as exc:
            raise self._error(f"cannot connect: {exc}", transient=True) from None
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._sock, self._stream = sock, sock.makefile("rb")
        try:
            hello = self._exchange(f"HELLO {PROTOCOL}")
            if hello.split()[:1] != [PROTOCOL]:
                raise self._error(f"answered HELLO with {hello!r}, not {PROTOCOL}")
            self._identity = hello[len(PROTOCOL):].strip()
            self.sensor = self._sensor(self._exchange("SENSOR?"))
        except DeviceError:
            self._drop()
            raise

    # -- exchanges ------------------------------------------------------------------------------
    def _expose(self, exposure_s: float, window: Window | None, dark: bool) -> Frame:
        """EXPOSE, sleep the exposure + readout on our clock (keep-alives run), READ."""
        window = self.full_window() if window is None else window
        x0, y0, width, height = (int(v) for v in (window.x0, window.y0, window.width, window.height))
        request = f"EXPOSE {float(exposure_s)!r} {int(dark)} {x0} {y0} {width} {height}"   # repr: exact
        reply = self._request(request)
        try:
            duration_s = float(reply)
        except ValueError:
            duration_s = math.nan
        if not (math.isfinite(duration_s) and duration_s >= 0):
            raise self._error(f"answered {request!r} with {reply!r}, not a duration in seconds")
        self.clock.sleep(duration_s)
        return self._read_frame(window, dark)

    def _read_frame(self, window: Window, dark: bool) -> Frame:
        header = self._request("READ").split()
        try:
            kind, width, height, exposure, start, is_dark, nbytes = header
            shape = (int(height), int(width))
            exposure_s, start_s, size = float(exposure), float(start), int(nbytes)
        except ValueError:
            self._drop()                                  # what follows the header is unknown: resynchronise
            raise self._error(f"malformed frame header {' '.join(header)!r}") from None
        if (kind != "FRAME" or shape != (window.height, window.width) or is_dark != str(int(dark))
                or size != 2 * window.width * window.height):
            self._drop()
            raise self._error(f"frame header {' '.join(header)!r} does not match the exposure of "
                              f"{window} (dark {int(dark)})")
        data = self._receive(size)
        pixels = np.frombuffer(data, dtype="<u2").astype(np.uint16).reshape(shape)
        return Frame(pixels, exposure_s, window, dark=dark, meta={"start_s": start_s})

    def _request(self, line: str) -> str:
        """`_exchange`, reconnecting first if a transient fault dropped the connection."""
        if self._sock is None:
            if self._closed:
                raise self._error(f"cannot send {line!r}: the camera was closed")
            self._connect()
        return self._exchange(line)

    def _exchange(self, line: str) -> str:
        """Send one request; the text after `OK` of its reply line (DeviceError for `ERR`)."""
        if self._sock is None or self._stream is None:
            raise self._error(f"cannot send {line!r}: not connected")
        try:
            self._sock.sendall(line.encode("ascii") + b"\n")
            raw = self._stream.readline()
        except TimeoutError:
            self._drop()
            raise self._error(f"no reply to {line!r} within {self.timeout_s:g} s", transient=True) from None
        except OSError as exc:
            self._drop()
            raise self._error(f"connection lost during {line!r}: {exc}", transient=True) from None
        if not raw.endswith(b"\n"):
            self._drop()
            raise self._error(f"connection closed before the reply to {line!r} (got {raw!r})", transient=True)
        text = raw.decode("ascii", "backslashreplace").rstrip("\r\n")
        if text == "OK" or text.startswith("OK "):
            return text[3:]
        if text.startswith("ERR busy"):
            self._drop()
            raise self._error(f"the served rig is in use by another client ({text[4:]})")
        if text.startswith("ERR "):
            raise self._error(f"refused {line!r}: {text[4:]}")
        self._drop()
        raise self._error(f"answered {line!r} with {text!r}, neither OK nor ERR", transient=True)

    def _receive(self, size: int) -> bytes:
        """The frame's `size` bytes of pixels."""
        assert self._stream is not None, "called right after the READ header arrived"
        data = bytearray()
        try:
            while len(data) < size and (chunk := self._stream.read1(size - len(data))):
                data += chunk
        except TimeoutError:
            pass
        except OSError as exc:
            self._drop()
            raise self._error(f"connection lost reading the frame's pixels: {exc}", transient=True) from None
        if len(data) != size:
            self._drop()
            raise self._error(f"short frame: {len(data)} of {size} bytes of pixels within {self.timeout_s:g} s",
                              transient=True)
        return bytes(data)

    def _sensor(self, reply: str) -> SensorInfo:
        try:
            return SensorInfo(**json.loads(reply))
        except (ValueError, TypeError) as exc:
            raise self._error(f"malformed SENSOR? reply {reply!r}: {exc}") from None

    def _error(self, what: str, *, transient: bool = False) -> DeviceError:
        return DeviceError(self.name, f"served camera at {self.address}: {what}", transient=transient)

    def _drop(self) -> None:
        """Forget the connection (the server then frees the session)."""
        if self._stream is not None:
            self._stream.close()
        if self._sock is not None:
            self._sock.close()
        self._sock = self._stream = None
