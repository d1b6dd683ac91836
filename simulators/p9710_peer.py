"""Protocol peer of the Gigahertz-Optik P9710 optometer on a pseudo-terminal.

The driver talks to it exactly as to the instrument on a serial port: the peer
owns a pty pair and hands out the slave path (`/dev/pts/N`), which pyserial
opens like any tty (see `rig.simulators.line_peer`).

Reply formats are our reading of the one open-source driver (no public
manual): one LF-terminated ASCII line per command; `MA` answers e.g.
`5.0012E-06`, or `OVER` when the current exceeds the present range.
"""

from __future__ import annotations

from rig.simulators.faults import METER_FAULTS
from rig.simulators.line_peer import LinePeer
from rig.simulators.world import SimWorld

#: Full scale of ranges 0 … 7 (2 mA … 200 pA).
FULL_SCALE_A = tuple(2e-3 * 10.0 ** -r for r in range(8))
OVERRANGE = "OVER"


def range_for(current_a: float) -> int:
    """Most sensitive range whose full scale holds the current (0 when none does)."""
    return max((r for r, fs in enumerate(FULL_SCALE_A) if abs(current_a) < fs), default=0)


class P9710Peer(LinePeer):
    """Simulated P9710 with a photodiode head at the sample plane of a SimWorld.

    Photocurrent = E⊥(now) × responsivity × (1 + relative noise); the default
    responsivity is the inverse of the configured calibration factor, so a
    driver with the right factor reads back E⊥. Powers up on range 0 with
    autorange off (`SB1` switches it on).
    """

    IDENTITY = "P9710 V5.6"
    SERIAL = "97100042"
    DETECTOR = "VL-3701"
    FAULTS = METER_FAULTS
    SHORT_FRACTION = 1.0        # the whole reply, without its terminator

    def __init__(self, world: SimWorld, *, responsivity_a_per_lx: float | None = None):
        super().__init__("pty")
        self.world = world
        self.responsivity_a_per_lx = (1.0 / world.config.meter.calibration_lx_per_a
                                      if responsivity_a_per_lx is None else responsivity_a_per_lx)
        self.autorange = False
        self.range = 0

    def respond(self, line: bytes) -> bytes | None:
        """Injected faults spoil the replies to `MA` only; `overrange` replaces the reading."""
        command = line.decode("ascii", "replace").strip().upper()
        fault = self.take_fault() if command == "MA" else None
        if fault == "no_reply":
            return None
        return self.wire(OVERRANGE if fault == "overrange" else self._reply(command), fault)

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
