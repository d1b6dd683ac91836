"""Gigahertz-Optik P-9710 optometer over RS-232 (9600 8N1, LF), as an IlluminanceMeter.

The protocol is the manual's (P-9710 Operating Manual V1.20, §15 Remote
Interface; contract in docs/p9710.md): one LF-terminated command line, one
LF-terminated answer line. A command without an answer is acknowledged by a
bare LF; any error by `?x`, x a sum of the error bits below. Such a code is
the meter's own verdict (a refused command, an overloaded input), so it is a
persistent DeviceError naming its meaning and is never retried; a garbled,
cut-off or missing reply is a transient fault, retried after a reconnect.

`TD0` comes first on every connect: a meter left in the `TD1` mode (by another
program or an earlier session; §15.3.9) acknowledges with `#` and answers an
error with `*` instead of the bare LF and `?x` this driver reads. `TD0` itself
may be acknowledged either way (the manual does not say which mode answers it).

An underload (`?32` to a reading: less light than the range resolves, e.g. the
lamp off or the detector covered) is not a failure of the meter but a reading
in the dark: `read` returns it flagged (`IlluminanceReading.floor_a`, the
floor of the range `GR` then reports), with the midpoint of [0, floor) as its
value; rig.physics.illuminance.estimate_of_readings refuses such a reading as an E⊥.

Illuminance = photocurrent (`MA`) × the detector's certificate factor from the
rig configuration, which the dataset records; `MV` (the meter's own calibrated
value) is never used, so a factor stored in the head cannot silently differ
from the recorded one. `GR` rides on the same command line as `MA` (`MA;GR`),
so the range reported is the one the reading was taken on and the reading's
uncertainty can follow it. Autorange (`SB1`) and the integration time (`SN`)
are set on every connect: they live in the meter's RAM, and the front panel can
change them. Commands that write the head's EEPROM or need a code (SP, SC, SE,
TS, TE, SF, TA, RA) are never sent.
"""

from __future__ import annotations

import re
from typing import Any

from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.core.values import IlluminanceReading
from rig.drivers.interfaces import IlluminanceMeter
from rig.drivers.line_instrument import Acknowledgement, LineInstrument, Query, Setting, UnexpectedReply
from rig.drivers.retry import DEFAULT_RETRY, RetryPolicy
from rig.drivers.transport import PortOpener, open_pyserial

#: §15.4: the bits of an error reply `?x`.
ERROR_BITS = {
    1: "command not allowed",
    2: "command parameter not allowed",
    4: "wrong code number",
    8: "parameter out of limits",
    16: "input signal overload (more than the 2 mA top range holds: direct lamp light?)",
    32: "input signal underload (less than the 200 pA range resolves: no light on the detector?)",
    64: "EEPROM write error",
}
_ERROR_REPLY = re.compile(r"\?(\d+)")
#: The two identity forms: the manual's `P-9710 4.7` and a firmware 5.6 unit's `P9710 V5.6`.
_IDENTITY = re.compile(r"P-?9710 V?\d+(\.\d+)+")
_NUMBER = re.compile(r"[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?")
RANGE_REPLIES = {str(r): r for r in range(8)}      # 0 = 2 mA full scale … 7 = 200 pA (most sensitive)
#: The error bit of an underload: less current than the range resolves.
UNDERLOAD = 32
#: The floor of ranges 0 … 7: the last digit each displays (§12.2: ±2.000 mA … ±200.0 pA, full scale / 2000).
RANGE_FLOOR_A = tuple(1e-6 * 10.0 ** -r for r in range(8))
#: `SN` takes the CW integration time in steps of 0.1 ms, 1 … 59999.
INTEGRATION_STEP_S = 1e-4
INTEGRATION_STEPS = range(1, 60000)


def error_meaning(code: int) -> str:
    """The meaning of error reply `?code`: each set bit's, joined; bits the manual does not define say so."""
    meanings = [text for bit, text in ERROR_BITS.items() if code & bit]
    unknown = code & ~sum(ERROR_BITS)
    if unknown or not meanings:
        meanings.append(f"undocumented error bits {unknown}")
    return " + ".join(meanings)


class MeterRefusal(DeviceError):
    """An error reply `?code`: the meter's verdict on the line (persistent)."""

    def __init__(self, device: str, message: str, code: int):
        super().__init__(device, message)
        self.code = code


def _plain_mode_acknowledged(reply: str) -> None:
    """`TD0`'s acknowledgement: the bare line feed of the mode it sets, or `#` from the `TD1` mode it leaves."""
    if reply not in ("", "#"):
        raise UnexpectedReply("{command!r} answered {reply!r}, not the bare line feed or the '#' that acknowledge it")


def _range(reply: str) -> int:
    if reply not in RANGE_REPLIES:
        raise UnexpectedReply("{command!r} answered {reply!r}, not a range 0…7")
    return RANGE_REPLIES[reply]


def _current_and_range(reply: str) -> tuple[float, int]:
    """`MA;GR`'s answer: `<current>;<range>`, the answers separated by the spacer the command used."""
    current, spacer, range_index = reply.partition(";")
    if not spacer or not _NUMBER.fullmatch(current) or range_index not in RANGE_REPLIES:
        raise UnexpectedReply("{command!r} answered {reply!r}, not '<current>;<range 0…7>'")
    return float(current), RANGE_REPLIES[range_index]


# -- the command table (§15.3) ---------------------------------------------------------------------
PLAIN_ACKNOWLEDGEMENT = Query("TD0", _plain_mode_acknowledged)   # no `#`/`*` acknowledge characters
MODEL = Query("GI", str)                   # software version: `P-9710 x.x` (manual) or `P9710 V5.6`
SERIAL_NUMBER = Query("TT", str)
DETECTOR = Query("GK", str)
AUTORANGE_ON = Setting("SB1")
INTEGRATION_TIME = Setting("SN{}", "0.1 ms")
READING = Query("MA;GR", _current_and_range, "A")     # photocurrent and the range it was measured on
RANGE = Query("GR", _range)


class P9710(LineInstrument, IlluminanceMeter):
    """Connects on construction (identity checked, autorange on, integration time set).

    A reading's reply may take the integration time plus the autoranger's settling
    (`autorange_s`) longer than other replies; `timeout_s` is the link's own margin.
    `events(kind, **fields)` hears retries.
    """

    #: A command without an answer is acknowledged by a bare line feed (`?x` is the meter's refusal).
    confirmation = Acknowledgement("the bare line feed that acknowledges it")

    def __init__(self, url: str, *, calibration_lx_per_a: float, clock: Clock, name: str = "meter",
                 timeout_s: float = 1.0, retry: RetryPolicy = DEFAULT_RETRY, integration_s: float = 0.2,
                 autorange_s: float = 0.2, open_port: PortOpener = open_pyserial):
        steps = round(integration_s / INTEGRATION_STEP_S)
        if steps not in INTEGRATION_STEPS:
            raise ValueError(f"{name}: integration time {integration_s:g} s is outside the P-9710's "
                             f"0.1 ms … 5.9999 s")
        super().__init__(url, name=name, clock=clock, timeout_s=timeout_s, retry=retry, baudrate=9600,
                         open_port=open_port)
        self.calibration_lx_per_a = calibration_lx_per_a
        self.integration_steps = steps
        self.reading_timeout_s = steps * INTEGRATION_STEP_S + autorange_s + timeout_s
        self._identity = ""
        self._heard = False          # whether any complete reply line has arrived
        self._opened = False         # whether the port ever opened (a silent meter, not a missing port)
        try:
            self.retrying("connect", self.reconnect, reconnect=False)    # reconnect() opens the port itself
        except DeviceError as exc:
            self.link.close()
            if not exc.unanswered or self._heard or not self._opened:
                raise
            # Outside the "Remote RS232" mode the meter takes no commands: the likeliest silence at connect.
            raise DeviceError(self.name, f"{str(exc).removeprefix(f'{self.name}: ')} (is the meter's menu Mode "
                                         f"set to \"Remote RS232\"?)", unanswered=True) from exc

    @classmethod
    def from_rig(cls, *, clock: Clock, settings: Any, address: str, timeout_s: float = 1.0) -> P9710:
        """The rig-file contract (rig.drivers.registry): `settings` is the rig file's `meter` section."""
        return cls(address, calibration_lx_per_a=settings.calibration_lx_per_a, clock=clock, timeout_s=timeout_s,
                   integration_s=settings.integration_s, autorange_s=settings.autorange_s)

    # -- IlluminanceMeter ----------------------------------------------------------------------
    def identity(self) -> str:
        return self._identity

    def read(self) -> IlluminanceReading:
        """One measurement: the meter integrates, autoranges, then answers current and range. An underload
        is a reading below the floor of the range the meter is on (`GR`), flagged by `floor_a`."""
        try:
            current, range_index = self.retrying(
                READING.text(), lambda: self.ask(READING, timeout_s=self.reading_timeout_s))
        except MeterRefusal as exc:
            if exc.code != UNDERLOAD:
                raise
            range_index = self.measuring_range()
            floor = RANGE_FLOOR_A[range_index]
            return IlluminanceReading(floor / 2 * self.calibration_lx_per_a, floor / 2, self.calibration_lx_per_a,
                                      range_index=range_index, floor_a=floor)
        return IlluminanceReading(current * self.calibration_lx_per_a, current, self.calibration_lx_per_a,
                                  range_index=range_index)

    # -- further commands ----------------------------------------------------------------------
    def measuring_range(self) -> int:
        """Present range, 0 (2 mA full scale) … 7 (200 pA), as chosen by the autoranger."""
        return self.query(RANGE)

    # -- protocol ------------------------------------------------------------------------------
    def reconnect(self) -> None:
        """(Re)open the port, switch the `#`/`*` acknowledgements off, check that a P-9710 answers, switch
        autorange on and set the integration time (a retry's way back, as a power-cycled or hand-operated meter
        may have lost them)."""
        self.link.reconnect()
        self._opened = True
        self.ask(PLAIN_ACKNOWLEDGEMENT)
        model = self.ask(MODEL)
        if not _IDENTITY.fullmatch(model):
            raise DeviceError(self.name, f"{MODEL.text()!r} answered {model!r}: not a P-9710")
        serial_no, detector = self.ask(SERIAL_NUMBER), self.ask(DETECTOR)
        self.put(AUTORANGE_ON)
        self.put(INTEGRATION_TIME, self.integration_steps)
        self._identity = f"Gigahertz-Optik {model} SN {serial_no} detector {detector}"

    def check_refusal(self, line: str, reply: str) -> None:
        """`?x` is the meter's verdict: a persistent MeterRefusal naming the code's meaning."""
        self._heard = True
        refused = _ERROR_REPLY.fullmatch(reply)
        if refused:
            code = int(refused[1])
            raise MeterRefusal(self.name, f"{line!r} answered {reply!r}: {error_meaning(code)}", code)
