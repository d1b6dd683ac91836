"""Protocol peer of the Gigahertz-Optik P9710 optometer on a pseudo-terminal.

The driver talks to it exactly as to the instrument on a serial port: the peer
owns a pty pair, hands out the slave path (`/dev/pts/N`, which pyserial opens
like any tty) and answers on the master from a reader thread. The slave fd
stays open in the peer so the master never sees EIO between driver
(re)connections. A pty has no modem lines: RTS/DTR ioctls fail on it, so the
driver must not touch them.

Reply formats are our reading of the one open-source driver (no public
manual): one LF-terminated ASCII line per command; `MA` answers e.g.
`5.0012E-06`, or `OVER` when the current exceeds the present range.
"""

from __future__ import annotations

import os
import select
import threading
import tty
from collections import deque

from rig.simulators.world import SimWorld

#: Full scale of ranges 0 … 7 (2 mA … 200 pA).
FULL_SCALE_A = tuple(2e-3 * 10.0 ** -r for r in range(8))
OVERRANGE = "OVER"
FAULTS = ("no_reply", "garbled", "short", "overrange")


def range_for(current_a: float) -> int:
    """Most sensitive range whose full scale holds the current (0 when none does)."""
    return max((r for r, fs in enumerate(FULL_SCALE_A) if abs(current_a) < fs), default=0)


class PtyLinePeer:
    """A line-oriented serial device on a pseudo-terminal; subclasses say what it answers."""

    def __init__(self) -> None:
        self.path: str | None = None
        self._fds: tuple[int, int, int, int] | None = None   # master, slave, wake-up pipe r, w
        self._thread: threading.Thread | None = None

    def answer(self, line: bytes) -> bytes | None:
        """Bytes to send back for one received line (LF stripped, nothing else); None sends nothing."""
        raise NotImplementedError

    def start(self) -> str:
        """Open the pty and start answering; returns the slave device path for pyserial."""
        if self._thread is not None:
            raise RuntimeError(f"{type(self).__name__} already started on {self.path}")
        master, slave = os.openpty()
        tty.setraw(master)
        wake_r, wake_w = os.pipe()
        self._fds = (master, slave, wake_r, wake_w)
        self.path = os.ttyname(slave)
        self._thread = threading.Thread(target=self._serve, name=f"{type(self).__name__} {self.path}",
                                        daemon=True)
        self._thread.start()
        return self.path

    def stop(self) -> None:
        """Stop the reader thread and close every fd; safe to call twice."""
        if self._thread is None:
            return
        os.write(self._fds[3], b"x")
        self._thread.join()
        for fd in self._fds:
            os.close(fd)
        self._thread = self._fds = None

    def __enter__(self) -> "PtyLinePeer":
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def _serve(self) -> None:
        master, _, wake_r, _ = self._fds
        pending = b""
        while True:
            ready, _, _ = select.select([master, wake_r], [], [])
            if wake_r in ready:
                return
            pending += os.read(master, 4096)
            *lines, pending = pending.split(b"\n")
            for line in lines:
                reply = self.answer(line)
                if reply is not None:
                    os.write(master, reply)


class P9710Peer(PtyLinePeer):
    """Simulated P9710 with a photodiode head at the sample plane of a SimWorld.

    Photocurrent = E⊥(now) × responsivity × (1 + relative noise); the default
    responsivity is the inverse of the configured calibration factor, so a
    driver with the right factor reads back E⊥. Powers up on range 0 with
    autorange off (`SB1` switches it on).
    """

    IDENTITY = "P9710 V5.6"
    SERIAL = "97100042"
    DETECTOR = "VL-3701"

    def __init__(self, world: SimWorld, *, responsivity_a_per_lx: float | None = None):
        super().__init__()
        self.world = world
        self.responsivity_a_per_lx = (1.0 / world.config.meter.calibration_lx_per_a
                                      if responsivity_a_per_lx is None else responsivity_a_per_lx)
        self.autorange = False
        self.range = 0
        self._faults: deque[str] = deque()

    def inject(self, fault: str, count: int = 1) -> None:
        """Spoil the replies to the next `count` `MA` requests with `fault` (one of FAULTS)."""
        if fault not in FAULTS:
            raise ValueError(f"unknown fault {fault!r}; known: {', '.join(FAULTS)}")
        if count < 1:
            raise ValueError(f"count must be at least 1, got {count}")
        self._faults.extend([fault] * count)

    def answer(self, line: bytes) -> bytes | None:
        command = line.decode("ascii", "replace").strip().upper()
        fault = self._faults.popleft() if command == "MA" and self._faults else None
        if fault == "no_reply":
            return None
        reply = OVERRANGE if fault == "overrange" else self._reply(command)
        if fault == "garbled":               # line noise: high bits set, terminator intact
            return bytes(b | 0x80 for b in reply.encode("ascii")) + b"\n"
        if fault == "short":
            return reply.encode("ascii")
        return reply.encode("ascii") + b"\n"

    def _reply(self, command: str) -> str:
        match command:
            case "GI":
                return self.IDENTITY
            case "TT":
                return self.SERIAL
            case "GK":
                return self.DETECTOR
            case "SB0" | "SB1":
                self.autorange = command == "SB1"
                return "OK"
            case "GR":
                return str(self.range)
            case "MA":
                return self._measure()
        return "ERR"

    def _measure(self) -> str:
        """Overrange if the current exceeds the present range; autorange then settles for the next."""
        noise = self.world.config.simulation.meter_noise_rel
        current = self.world.illuminance_normal_lx() * self.responsivity_a_per_lx
        if noise:
            current *= 1.0 + self.world.rng.normal(0.0, noise)
        over = abs(current) >= FULL_SCALE_A[self.range]
        if self.autorange:
            self.range = range_for(current)
        return OVERRANGE if over else f"{current:.4E}"
