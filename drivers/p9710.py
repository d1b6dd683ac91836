"""Gigahertz-Optik P9710 optometer over RS-232 (9600 8N1, LF), as an IlluminanceMeter.

Illuminance = photocurrent (`MA`) × the detector's certificate factor from the
rig configuration, which the dataset records; `MV` (the meter's own calibrated
value) is never used, so a factor stored in the meter cannot silently differ
from the recorded one. The meter autoranges (`SB1`, sent on every connect, as
a power-cycled meter forgets it), so an over- or underrange answer means the
range is still settling: it is retried like a timeout or a garbled line.

There is no public manual; commands and reply formats follow the one
open-source driver (github.com/matusm/Bev.Instruments.P9710): one LF-terminated
ASCII reply per command. `OVER`/`UNDER` for out-of-range readings is our
assumption.
"""

from __future__ import annotations

import re
from typing import Callable, TypeVar

from rig.drivers.interfaces import IlluminanceMeter
from rig.drivers.retry import RetryPolicy, call_with_retry
from rig.drivers.transport import EventSink, LineTransport, no_events

from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.core.values import IlluminanceReading

T = TypeVar("T")

_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")
OUT_OF_RANGE = {"OVER": "overrange", "UNDER": "underrange"}
RANGE_REPLIES = {str(r): r for r in range(8)}      # 0 = 2 mA full scale … 7 = 200 pA


class P9710(IlluminanceMeter):
    """Connects on construction (identity checked, autorange on); `events(kind, **fields)` hears retries."""

    def __init__(self, url: str, *, calibration_lx_per_a: float, clock: Clock, name: str = "meter",
                 timeout_s: float = 1.0, retry: RetryPolicy = RetryPolicy(), integration_s: float = 0.2):
        self.name = name
        self.calibration_lx_per_a = calibration_lx_per_a
        self.clock = clock
        self.retry = retry
        self.integration_s = integration_s
        self.events: EventSink = no_events
        self._link = LineTransport(name, url, timeout_s=timeout_s, baudrate=9600)
        self._identity = ""
        try:
            self._retrying("connect", self._connect, reconnect=False)   # _connect reopens the port itself
        except DeviceError:
            self._link.close()
            raise

    # -- IlluminanceMeter ----------------------------------------------------------------------
    def identity(self) -> str:
        return self._identity

    def read(self) -> IlluminanceReading:
        current = self._retrying("MA", self._photocurrent)
        return IlluminanceReading(current * self.calibration_lx_per_a, current, self.calibration_lx_per_a)

    def close(self) -> None:
        self._link.close()

    # -- further commands ----------------------------------------------------------------------
    def measuring_range(self) -> int:
        """Present range, 0 (2 mA full scale) … 7 (200 pA), as chosen by the autoranger."""
        return self._retrying("GR", self._range)

    # -- protocol ------------------------------------------------------------------------------
    def _connect(self) -> None:
        """(Re)open the port, check that a P9710 answers and switch autorange on."""
        self._link.reconnect()
        model = self._link.query("GI")
        if not model.startswith("P9710"):
            raise DeviceError(self.name, f"'GI' answered {model!r}: not a P9710")
        serial_no, detector = self._link.query("TT"), self._link.query("GK")
        self._link.query("SB1")     # the reply's content is undocumented; reading it keeps replies in step
        self._identity = f"Gigahertz-Optik {model} SN {serial_no} detector {detector}"

    def _photocurrent(self) -> float:
        self.clock.sleep(self.integration_s)     # one integration per reading (and per retry)
        reply = self._link.query("MA")
        if reply in OUT_OF_RANGE:
            raise DeviceError(self.name, f"{OUT_OF_RANGE[reply]}: 'MA' answered {reply!r}", transient=True)
        if not _NUMBER.fullmatch(reply):
            raise DeviceError(self.name, f"non-numeric reply to 'MA': {reply!r}", transient=True)
        return float(reply)

    def _range(self) -> int:
        reply = self._link.query("GR")
        if reply not in RANGE_REPLIES:
            raise DeviceError(self.name, f"'GR' answered {reply!r}, not a range 0…7", transient=True)
        return RANGE_REPLIES[reply]

    def _retrying(self, what: str, action: Callable[[], T], *, reconnect: bool = True) -> T:
        """Run `action` under the retry policy, reconnecting before each retry."""
        return call_with_retry(action, device=self.name, what=what, clock=self.clock, policy=self.retry,
                               on_retry=lambda kind, **fields: self.events(kind, **fields),
                               reconnect=self._connect if reconnect else None)
