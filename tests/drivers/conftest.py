"""In-memory protocol replay for the drivers' byte-exact tests (PyMeasure's `expected_protocol`).

`expected_protocol(exchanges)` scripts a device as (request bytes, reply bytes)
pairs and hands out an opener to build the real driver over it: every byte the
driver writes must be the next scripted request, every read returns that
request's scripted reply, and the test fails on an unexpected write, a read
where no reply is scripted, or an exchange the driver never made. Nothing
listens on a socket or a pty, and no thread runs.

Line instruments take `open_port=replay.open_port`; a reply may be b"" (a
timeout: nothing arrived) or lack its terminator (a short reply). Modbus
controllers take `open_client=replay.open_client` and the exchanges are PDUs
(function code and data, Modbus/TCP header stripped); a reply of None is no
reply at all (the request times out).
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from dataclasses import dataclass, field
from typing import NoReturn

import pytest
from pymodbus.client import ModbusTcpClient

from rig.simulators.clock import SimClock

Exchange = tuple[bytes, bytes | None]


@pytest.fixture
def clock() -> SimClock:
    """The rig clock of a driver under test: simulated, unpaced."""
    return SimClock(pace=0)


@pytest.fixture
def events() -> list[tuple[str, dict]]:
    """Collects what a driver reports (`driver.events = lambda kind, **f: events.append((kind, f))`)."""
    return []


@pytest.fixture
def no_leaks() -> Iterator[None]:
    """Every pty, port and reader thread a test opened is closed by its end."""
    fds, threads = set(os.listdir("/proc/self/fd")), set(threading.enumerate())
    yield
    assert set(os.listdir("/proc/self/fd")) == fds
    assert set(threading.enumerate()) == threads


@dataclass
class Replay:
    """The script, and what the driver did with it (`written`: each request with the rig time it came)."""

    exchanges: list[Exchange]
    now: Callable[[], float] = lambda: 0.0
    written: list[tuple[bytes, float]] = field(default_factory=list)
    #: The port's timeout (s) at each read: what the driver was prepared to wait for each reply.
    read_timeouts: list[float | None] = field(default_factory=list)
    opens: int = 0
    _reply: bytes | None = None
    _problems: list[str] = field(default_factory=list)

    # -- the script ------------------------------------------------------------------------------
    def request(self, data: bytes) -> bytes | None:
        """Take the next exchange for `data`; its reply, or fail the test."""
        step = len(self.written)
        self.written.append((data, self.now()))
        if step >= len(self.exchanges):
            self._fail(f"unexpected request #{step}: {data!r} (the script has {len(self.exchanges)})")
        expected, reply = self.exchanges[step]
        if data != expected:
            self._fail(f"request #{step}: expected {expected!r}, got {data!r}")
        return reply

    def _fail(self, problem: str) -> NoReturn:
        self._problems.append(problem)
        raise AssertionError(problem)

    def check_complete(self) -> None:
        assert not self._problems, self._problems
        missing = self.exchanges[len(self.written):]
        assert not missing, f"exchanges the driver never made: {missing}"

    # -- a pyserial port ---------------------------------------------------------------------------
    def open_port(self, url: str, *, baudrate: int, timeout: float, write_timeout: float) -> ReplayPort:
        self.opens += 1
        return ReplayPort(self, timeout)

    # -- a pymodbus client -------------------------------------------------------------------------
    def open_client(self, url: str, timeout_s: float) -> ReplayModbusClient:
        return ReplayModbusClient(self, timeout_s)


class ReplayPort:
    """A pyserial port whose far end is the script: one write is one request."""

    def __init__(self, replay: Replay, timeout: float | None = None):
        self.replay = replay
        self.timeout = timeout
        self.is_open = True
        self._pending: bytes | None = None

    def write(self, data: bytes, /) -> int:
        assert self.is_open, f"write {data!r} on a closed port"
        self._pending = self.replay.request(data)
        return len(data)

    def flush(self) -> None:
        pass

    def reset_input_buffer(self) -> None:
        pass

    def read_until(self, expected: bytes = b"\n", size: int | None = None) -> bytes:
        self.replay.read_timeouts.append(self.timeout)
        if self._pending is None:
            self.replay._fail(f"read after {self.replay.written[-1][0]!r}, which has no reply in the script"
                              if self.replay.written else "read before any request")
        reply, self._pending = self._pending, None
        return reply or b""

    def close(self) -> None:
        self.is_open = False


class ReplayModbusClient(ModbusTcpClient):
    """pymodbus' Modbus/TCP client with the script in place of its socket; replies get the request's header."""

    def __init__(self, replay: Replay, timeout_s: float):
        super().__init__("replay", timeout=timeout_s, retries=0)
        self.replay = replay
        self._open = False
        self._incoming = b""

    @property
    def connected(self) -> bool:
        return self._open

    def connect(self) -> bool:
        if not self._open:
            self.replay.opens += 1
        self._open = True
        return True

    def close(self) -> None:
        self._open = False

    def send(self, request: bytes, addr: tuple | None = None) -> int:
        header, pdu = request[:7], request[7:]
        reply = self.replay.request(pdu)
        if reply is not None:
            self._incoming = header[:4] + (len(reply) + 1).to_bytes(2, "big") + header[6:7] + reply
        return len(request)

    def recv(self, size: int | None) -> bytes:
        data, self._incoming = self._incoming, b""
        return data


@pytest.fixture
def expected_protocol() -> Callable[..., AbstractContextManager[Replay]]:
    """`with expected_protocol(exchanges, now=clock.now) as replay:` build the driver with
    `replay.open_port` / `replay.open_client`; on leaving, every exchange must have been made."""

    @contextmanager
    def replaying(exchanges: list[Exchange], now: Callable[[], float] = lambda: 0.0) -> Iterator[Replay]:
        replay = Replay(list(exchanges), now)
        yield replay
        replay.check_complete()

    return replaying
