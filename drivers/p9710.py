"""Gigahertz-Optik P9710 optometer over RS-232 (9600 8N1, LF), as an IlluminanceMeter.

Illuminance = photocurrent (`MA`) × the detector's certificate factor from the
rig configuration, which the dataset records; `MV` (the meter's own calibrated
value) is never used, so a factor stored in the meter cannot silently differ
from the recorded one. The meter autoranges (`SB1`, sent on every connect, as
a power-cycled meter forgets it), so an over- or underrange answer means the
range is still settling: it is retried like a timeout or a garbled line.

Commands and reply formats follow the open-source driver
(github.com/matusm/Bev.Instruments.P9710): one LF-terminated ASCII reply per
command. `OVER`/`UNDER` for out-of-range readings is our assumption.
"""

from __future__ import annotations

import re

from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.core.values import IlluminanceReading
from rig.drivers.interfaces import IlluminanceMeter
from rig.drivers.line_instrument import LineInstrument, Query, UnexpectedReply
from rig.drivers.retry import DEFAULT_RETRY, RetryPolicy
from rig.drivers.transport import PortOpener, open_pyserial

_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")
OUT_OF_RANGE = {"OVER": "overrange", "UNDER": "underrange"}
RANGE_REPLIES = {str(r): r for r in range(8)}      # 0 = 2 mA full scale … 7 = 200 pA


def _photocurrent_a(reply: str) -> float:
    if reply in OUT_OF_RANGE:
        raise UnexpectedReply(f"{OUT_OF_RANGE[reply]}: {{command!r}} answered {{reply!r}}")
    if not _NUMBER.fullmatch(reply):
        raise UnexpectedReply("non-numeric reply to {command!r}: {reply!r}")
    return float(reply)


def _range(reply: str) -> int:
    if reply not in RANGE_REPLIES:
        raise UnexpectedReply("{command!r} answered {reply!r}, not a range 0…7")
    return RANGE_REPLIES[reply]


# -- the command table -----------------------------------------------------------------------------
MODEL = Query("GI", str)                   # type and firmware, e.g. `P9710 V5.6`
SERIAL_NUMBER = Query("TT", str)
DETECTOR = Query("GK", str)
#: Autorange on; the reply's content is undocumented, reading it keeps replies in step.
AUTORANGE_ON = Query("SB1", str)
PHOTOCURRENT = Query("MA", _photocurrent_a, "A")
RANGE = Query("GR", _range)                # 0 (2 mA full scale) … 7 (200 pA)


class P9710(LineInstrument, IlluminanceMeter):
    """Connects on construction (identity checked, autorange on); `events(kind, **fields)` hears retries."""

    def __init__(self, url: str, *, calibration_lx_per_a: float, clock: Clock, name: str = "meter",
                 timeout_s: float = 1.0, retry: RetryPolicy = DEFAULT_RETRY, integration_s: float = 0.2,
                 open_port: PortOpener = open_pyserial):
        super().__init__(url, name=name, clock=clock, timeout_s=timeout_s, retry=retry, baudrate=9600,
                         open_port=open_port)
        self.calibration_lx_per_a = calibration_lx_per_a
        self.integration_s = integration_s
        self._identity = ""
        try:
            self.retrying("connect", self.reconnect, reconnect=False)    # reconnect() opens the port itself
        except DeviceError:
            self.link.close()
            raise

    # -- IlluminanceMeter ----------------------------------------------------------------------
    def identity(self) -> str:
        return self._identity

    def read(self) -> IlluminanceReading:
        current = self.retrying(PHOTOCURRENT.text(), self._photocurrent)
        return IlluminanceReading(current * self.calibration_lx_per_a, current, self.calibration_lx_per_a)

    # -- further commands ----------------------------------------------------------------------
    def measuring_range(self) -> int:
        """Present range, 0 (2 mA full scale) … 7 (200 pA), as chosen by the autoranger."""
        return self.query(RANGE)

    # -- protocol ------------------------------------------------------------------------------
    def reconnect(self) -> None:
        """(Re)open the port, check that a P9710 answers and switch autorange on (a retry's way back)."""
        self.link.reconnect()
        model = self.ask(MODEL)
        if not model.startswith("P9710"):
            raise DeviceError(self.name, f"{MODEL.text()!r} answered {model!r}: not a P9710")
        serial_no, detector = self.ask(SERIAL_NUMBER), self.ask(DETECTOR)
        self.ask(AUTORANGE_ON)
        self._identity = f"Gigahertz-Optik {model} SN {serial_no} detector {detector}"

    def _photocurrent(self) -> float:
        self.clock.sleep(self.integration_s)     # one integration per reading (and per retry)
        return self.ask(PHOTOCURRENT)
