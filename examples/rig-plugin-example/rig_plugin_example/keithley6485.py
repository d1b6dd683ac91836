"""Keithley 6485 picoammeter reading a calibrated photodiode: an illuminance meter for rig.

SCPI over RS-232 (9600 8N1, LF; the instrument's front panel: COMM → RS-232, terminator LF).
`READ?` triggers one measurement and answers `reading,timestamp,status`, e.g.
`-1.234567E-09A,+1.234567E+03,+0.000000E+00`; illuminance = photocurrent × the photodiode's
certificate factor, the rig file's `meter.calibration_lx_per_a`, as for rig's own P-9710.

A plug-in is a class with `ROLE` (inherited here from IlluminanceMeter) and the classmethod
`from_rig(*, clock, settings, **options)`; it is registered in pyproject.toml under the
entry-point group `rig.drivers`. rig's command-table base (`LineInstrument`) brings the line
transport, the retry policy and the error handling every rig driver shares.
"""

from __future__ import annotations

from typing import Any

from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.core.values import IlluminanceReading
from rig.drivers.interfaces import IlluminanceMeter
from rig.drivers.line_instrument import LineInstrument, Query, Setting
from rig.drivers.retry import DEFAULT_RETRY


def _current_a(reply: str) -> float:
    """`READ?`'s first field, the current with its unit letter: `-1.234567E-09A`."""
    reading = reply.split(",")[0]
    if not reading.endswith("A"):
        raise ValueError(reply)
    return abs(float(reading[:-1]))          # the photodiode's sign depends on how it is wired


IDENTITY = Query("*IDN?", str)
RESET = Setting("*RST")
AUTORANGE = Setting("SENSe:CURRent:RANGe:AUTO ON")
READ = Query("READ?", _current_a, "A")


class Keithley6485(LineInstrument, IlluminanceMeter):
    """`address`: a serial port or a pyserial URL; `calibration_lx_per_a`: the photodiode's factor."""

    @classmethod
    def from_rig(cls, *, clock: Clock, settings: Any, address: str, timeout_s: float = 2.0) -> Keithley6485:
        """Built by rig from the rig file: `settings` is its `meter` section, the options the entry's keys."""
        return cls(address, clock=clock, calibration_lx_per_a=settings.calibration_lx_per_a, timeout_s=timeout_s)

    def __init__(self, address: str, *, clock: Clock, calibration_lx_per_a: float, timeout_s: float = 2.0):
        super().__init__(address, name="meter", clock=clock, timeout_s=timeout_s, retry=DEFAULT_RETRY, baudrate=9600)
        self.calibration_lx_per_a = calibration_lx_per_a
        self._identity = self.query(IDENTITY)
        if "6485" not in self._identity:
            self.close()
            raise DeviceError(self.name, f"'*IDN?' answered {self._identity!r}: not a Keithley 6485")
        self.send(RESET)
        self.send(AUTORANGE)

    def identity(self) -> str:
        return self._identity

    def read(self) -> IlluminanceReading:
        current = self.query(READ)
        return IlluminanceReading(current * self.calibration_lx_per_a, current, self.calibration_lx_per_a)
