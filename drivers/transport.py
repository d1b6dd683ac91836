"""Line-based transport over pyserial URLs: serial ports, `socket://host:port`, `loop://`, pty paths.

Both ASCII instruments (the SCPI lamp supply and the optometer) speak
request/reply lines; this is the one place that frames lines, enforces the
terminator (pyserial's readline returns partial data on timeout without
raising), reconnects a dropped link and turns every failure into a
`DeviceError` naming the device and what it answered. The port comes from
`open_port` (pyserial by default), so a test can put an in-memory port with a
scripted protocol under a real driver.
"""

from __future__ import annotations

import errno
import socket
from typing import Any, Protocol

import serial

from rig.core.errors import DeviceError


class Port(Protocol):
    """The part of a pyserial port the transport uses."""

    is_open: bool
    timeout: float | None

    def write(self, data: bytes, /) -> int | None: ...
    def flush(self) -> None: ...
    def reset_input_buffer(self) -> None: ...
    def read_until(self, expected: bytes = ..., size: int | None = ...) -> bytes: ...
    def close(self) -> None: ...


class PortOpener(Protocol):
    """`serial.serial_for_url`'s signature, as far as the transport calls it."""

    def __call__(self, url: str, *, baudrate: int, timeout: float, write_timeout: float) -> Port: ...


def open_pyserial(url: str, *, baudrate: int, timeout: float, write_timeout: float) -> Port:
    """A serial device path is opened exclusively (an advisory lock): a second program on the same port
    would interleave its exchanges with ours; it is told the port is busy instead."""
    options = {} if "://" in url else {"exclusive": True}
    port: Port = serial.serial_for_url(url, baudrate=baudrate, timeout=timeout, write_timeout=write_timeout,
                                       **options)
    return port


class LineTransport:
    def __init__(self, device: str, url: str, *, terminator: bytes = b"\n", timeout_s: float = 2.0,
                 baudrate: int = 9600, write_terminator: bytes | None = None, echo: bool = False,
                 open_port: PortOpener = open_pyserial):
        """`terminator` ends a reply: a line end, or a prompt (`> `) for a terminal-style instrument;
        `echo`: the instrument first repeats each line it receives, which `read_line` checks and strips."""
        self.device = device
        self.url = url
        self.terminator = terminator
        self.write_terminator = terminator if write_terminator is None else write_terminator
        self.echo = echo
        self.timeout_s = timeout_s
        self.baudrate = baudrate
        self._open_port = open_port
        self._port: Port | None = None

    # -- connection ---------------------------------------------------------------------------
    def open(self) -> Port:
        """The open port, opening it first if needed."""
        if self._port is not None:
            return self._port
        try:
            port = self._open_port(self.url, baudrate=self.baudrate, timeout=self.timeout_s,
                                   write_timeout=self.timeout_s)
        except (serial.SerialException, OSError, ValueError) as exc:
            if getattr(exc, "errno", None) == errno.ENOENT:      # transient: an adapter may come back
                raise DeviceError(self.device, f"cannot open {self.url}: the port does not exist (unplugged, "
                                               "renamed, or its server has stopped?)", transient=True) from None
            raise DeviceError(self.device, f"cannot open {self.url}: {exc}", transient=True) from None
        tcp = getattr(port, "_socket", None)
        if isinstance(tcp, socket.socket):
            # A setting followed by its error-queue query is two small writes before a read:
            # without TCP_NODELAY, Nagle + delayed ACK stall each exchange by ~40 ms.
            tcp.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._port = port
        return port

    def close(self) -> None:
        if self._port is None:
            return
        port: Any = self._port
        self._port = None
        tcp = getattr(port, "_socket", None)
        if isinstance(tcp, socket.socket):
            # pyserial's socket:// close() sleeps 0.3 s "for quick reconnects"; a reconnect
            # after a dropped link should not cost that, so release the socket here.
            tcp.close()
            port._socket = None
            port.is_open = False
        port.close()

    def reconnect(self) -> None:
        self.close()
        self.open()

    # -- exchange ------------------------------------------------------------------------------
    def write_line(self, line: str) -> None:
        port = self.open()
        try:
            port.reset_input_buffer()      # a late reply to an earlier request must not pair with this one
            port.write(line.encode("ascii") + self.write_terminator)
            port.flush()
        except (serial.SerialException, OSError) as exc:
            self.close()
            raise DeviceError(self.device, f"connection lost while sending {line!r}: {exc}", transient=True) from None

    def read_line(self, request: str, timeout_s: float | None = None) -> str:
        """One reply line; `timeout_s` replaces the link's timeout for this reply (a slow measurement)."""
        port = self.open()
        wait_s = self.timeout_s if timeout_s is None else timeout_s
        try:
            if timeout_s is not None:
                port.timeout = timeout_s
            try:
                raw = port.read_until(self.terminator)
            finally:
                if timeout_s is not None:
                    port.timeout = self.timeout_s
        except (serial.SerialException, OSError) as exc:
            self.close()
            raise DeviceError(self.device, f"connection lost waiting for the reply to {request!r}: {exc}",
                              transient=True) from None
        if not raw.endswith(self.terminator):
            if raw == b"" and getattr(port, "is_open", True) is False:
                self.close()
            raise DeviceError(self.device, f"no complete reply to {request!r} within {wait_s:g} s "
                              f"(got {raw!r})", transient=True)
        try:
            reply = raw[:-len(self.terminator)].decode("ascii")
        except UnicodeDecodeError:
            raise DeviceError(self.device, f"garbled reply to {request!r}: {raw!r}", transient=True) from None
        if self.echo:
            echo = request + self.write_terminator.decode("ascii")
            if not reply.startswith(echo):
                raise DeviceError(self.device, f"the reply to {request!r} does not begin with its echo: {raw!r}",
                                  transient=True)
            reply = reply[len(echo):]
        return reply.strip()

    def query(self, line: str, timeout_s: float | None = None) -> str:
        self.write_line(line)
        return self.read_line(line, timeout_s)
