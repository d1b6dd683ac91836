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

import pytest
from shared import Exchange, Replay

from rig.simulators.clock import SimClock


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
