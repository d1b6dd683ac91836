"""Protocol peer of the Gigahertz-Optik P-9710 optometer on a pseudo-terminal, rebuilt from its manual.

The driver talks to it exactly as to the instrument on a serial port: the peer
owns a pty pair and hands out the slave path (`/dev/pts/N`), which pyserial
opens like any tty (see `rig.simulators.line_peer`).

What it answers follows the P-9710 Operating Manual V1.20, §15 Remote
Interface, and what a firmware 5.6 unit answered in public captures
(github.com/matusm/Bev.Instruments.P9710.Detector, doc/dumpDetector1.txt and
doc/BruteForce.txt; github.com/matusm/Bev.Instruments.P9710, P9710.cs):

- a line of at most 100 characters + LF holds one or more commands, with or
  without spacers (`,` ` ` `;` TAB); the answers are joined with the spacer
  written between their commands; a line whose commands have no answer gets a
  bare LF;
- an error answers `?x` for the whole line: the first error met, the rest of
  the line is not executed (our choice: the manual does not say);
- measurements answer `+x.xxxxE+xx` after integrating (`SN` p × 0.1 ms; the
  peer spends that rig time) and, with autorange on, settling 20 ms per range
  step (the slower, -2 variant); a current above the 2 mA top range answers
  `?16`, below 0.1 pA (the last digit of range 7's 200.0 pA) on range 7 `?32`;
- `ST` and the code-protected or EEPROM-writing commands (SP, SC, SE, TS, TE,
  SF, TA, RA) answer `?4`, as the real unit answers `ST` without the right `RA`
  code: the peer knows no code, so its head EEPROM stays read-only;
- `TD1` (§15.3.9: "'#' and '*' (error) as answer") switches on acknowledge
  characters: a line whose commands have no answer is acknowledged by `#` LF
  instead of the bare LF, and an error line answers `*` LF instead of `?x`
  LF; lines with answers are unchanged. Our reading of a one-line entry: the
  manual shows no example. The mode in force once the line has run answers it
  (`TD0` is acknowledged by a bare LF, `TD1` by `#`); a meter can be powered up
  in either mode (`acknowledge_chars`), as one left in `TD1` would be.
"""

from __future__ import annotations

import re
from collections.abc import Callable

from rig.simulators.faults import METER_FAULTS
from rig.simulators.line_peer import LinePeer
from rig.simulators.world import SimWorld

SPACERS = ",; \t"
#: Full scale of ranges 0 … 7 (2 mA … 200 pA).
FULL_SCALE_A = tuple(2e-3 * 10.0 ** -r for r in range(8))
UNDERLOAD_A = 1e-13
RANGE_STEP_S = 0.02
INTEGRATION_STEP_S = 1e-4
#: The head connector's EEPROM (2048 bytes) as `GC0` … `GC63` read it from a VL head (dumpDetector1.txt:
#: `PT9610`, serial 0xCC8D = 52365, name `GO2000`, one calibration entry); the rest reads 255.
HEAD_EEPROM = bytes([
    80, 84, 57, 54, 49, 48, 141, 204, 0, 0, 0, 255, 255, 255, 0, 0,
    71, 79, 50, 48, 48, 48, 32, 32, 32, 32, 32, 32, 32, 32, 32, 32,
    0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
    86, 76, 159, 46, 7, 11, 32, 32, 0, 0, 0, 0, 0, 0, 0, 0,
]).ljust(2048, b"\xff")
PROTECTED = frozenset({"ST", "SP", "SC", "SE", "TS", "TE", "SF", "TA", "RA"})
MEASUREMENTS = frozenset({"MA", "MV", "MU"})
_TOKEN = re.compile(r"([A-Z]{2})([-+0-9.E]*)")
_INTEGER = re.compile(r"[-+]?\d+")


class MeterError(Exception):
    """The error code (§15.4) the line is answered with."""

    def __init__(self, code: int):
        super().__init__(code)
        self.code = code


def range_for(current_a: float) -> int:
    """Most sensitive range whose full scale holds the current (0 when none does)."""
    return max((r for r, fs in enumerate(FULL_SCALE_A) if abs(current_a) <= fs), default=0)


def integer(parameter: str, low: int, high: int) -> int:
    """A command's integer parameter: `?2` if it is none, `?8` if outside low … high."""
    if not _INTEGER.fullmatch(parameter):
        raise MeterError(2)
    value = int(parameter)
    if not low <= value <= high:
        raise MeterError(8)
    return value


def number(value: float) -> str:
    return f"{value:+.4E}"


class P9710Peer(LinePeer):
    """Simulated P-9710 with a photodiode head at the sample plane of a SimWorld.

    Photocurrent = E⊥(now) × responsivity × (1 + relative noise); the default
    responsivity is the inverse of the configured calibration factor, so a
    driver with the right factor reads back E⊥. Powers up on range 0 with
    autorange off and 100 ms integration.
    """

    SERIAL = "1875"
    VARIANT = "521"
    DETECTOR = "VL__"
    FAULTS = METER_FAULTS
    SHORT_FRACTION = 1.0        # the whole reply, without its terminator
    MAX_LINE = 100              # §15.1: a command line holds at most 100 characters

    def __init__(self, world: SimWorld, *, responsivity_a_per_lx: float | None = None,
                 identity: str = "P9710 V5.6", acknowledge_chars: bool = False):
        """`identity`: what `GI` answers, a real unit's `P9710 V5.6` or the manual's `P-9710 4.7`;
        `acknowledge_chars`: in the `TD1` mode (`#`/`*`) from the start."""
        super().__init__("pty")
        self.world = world
        self.identity = identity
        self.responsivity_a_per_lx = (1.0 / world.config.meter.calibration_lx_per_a
                                      if responsivity_a_per_lx is None else responsivity_a_per_lx)
        self.autorange = False
        self.range = 0
        self.integration_steps = 1000
        self.offset_a = 0.0
        self.calibration_entry = 0
        self.wavelength_nm = 555
        self.sync = False
        self.acknowledge_chars = acknowledge_chars
        self._last_current_a = 0.0           # SO1 takes it as the offset
        self._last_answer = 0.0              # of MA, MV or MU: GA, GB, GD, GP refer to it
        self._queries: dict[str, Callable[[], str]] = {
                 "GI": lambda: self.identity, "TF": lambda: self.VARIANT, "TT": lambda: self.SERIAL,
                 "GK": lambda: self.DETECTOR, "GU": lambda: "lx", "MB": lambda: "100%",
                 "GR": lambda: str(self.range), "MA": self._current, "MV": self._value, "MU": self._voltage,
                 "GA": lambda: number(self._peak(+1)), "GB": lambda: number(self._peak(-1)),
                 "GD": lambda: number(self._peak(+1) - self._peak(-1)), "GP": self._percent_of_range}
        self._with_parameter: dict[str, Callable[[str], str | None]] = {
            "SB": self._autorange, "SR": self._set_range, "SN": self._integration, "SO": self._offset,
            "SD": self._calibration, "SY": self._wavelength, "SS": self._sync, "TD": self._acknowledge,
            "GS": self._parameter, "GC": lambda p: str(HEAD_EEPROM[integer(p, 0, 2047)]),
        }

    # -- the line -----------------------------------------------------------------------------
    def respond(self, line: bytes) -> bytes | None:
        """Injected faults spoil the answers to lines that measure; `overload` answers `?16` instead."""
        commands = self.parse(line.decode("ascii", "replace"))
        fault = self.take_fault() if any(c in MEASUREMENTS for c, _ in commands) else None
        if fault == "no_reply":
            return None
        return self.wire(self.acknowledge("?16" if fault == "overload" else self.execute(commands)), fault)

    def acknowledge(self, answer: str) -> str:
        """The line's answer as the `TD` mode sends it: `#` for none and `*` for an error in `TD1`."""
        if not self.acknowledge_chars:
            return answer
        return "#" if not answer else "*" if answer.startswith("?") else answer

    def overlong(self) -> bytes | None:
        """A line over 100 characters: `?1` (command not allowed), at its LF."""
        return self.wire(self.acknowledge("?1"), None)

    @staticmethod
    def parse(text: str) -> list[tuple[str, str]]:
        """(mnemonic, parameter) pairs and spacers (`(",", "")`); the rest of the line from where it is not
        a command is one unknown mnemonic."""
        commands, at, upper = [], 0, text.upper()
        while at < len(text):
            if text[at] in SPACERS:
                commands.append((text[at], ""))
                at += 1
                continue
            match = _TOKEN.match(upper, at)
            if match is None:               # not a command: `?1` once the line gets this far
                commands.append((text[at:], ""))
                break
            commands.append((match[1], match[2]))
            at = match.end()
        return commands

    def execute(self, commands: list[tuple[str, str]]) -> str:
        """The answer line (no LF): answers joined by the spacer between their commands, or `?x`."""
        answer, spacer, answered = "", "", False
        try:
            for mnemonic, parameter in commands:
                if mnemonic in SPACERS:
                    spacer = mnemonic if answered else ""
                    continue
                reply = self._one(mnemonic, parameter)
                if reply is not None:
                    answer += spacer + reply
                    spacer, answered = "", True
        except MeterError as exc:
            return f"?{exc.code}"
        return answer

    def _one(self, mnemonic: str, parameter: str) -> str | None:
        if mnemonic in PROTECTED:
            raise MeterError(4)
        if mnemonic in self._queries:
            if parameter:
                raise MeterError(2)
            return self._queries[mnemonic]()
        if mnemonic in self._with_parameter:
            return self._with_parameter[mnemonic](parameter)
        raise MeterError(1)

    # -- measurement --------------------------------------------------------------------------
    def _measure(self) -> float:
        """Integrate (rig time passes), autoranging first; the input current minus the offset."""
        noise = self.world.config.simulation.meter_noise_rel
        current = self.world.illuminance_normal_lx() * self.responsivity_a_per_lx
        if noise:
            current *= 1.0 + self.world.rng.normal(0.0, noise)
        steps = 0
        if self.autorange:
            steps, self.range = abs(range_for(current) - self.range), range_for(current)
        self.world.spend_s(self.integration_steps * INTEGRATION_STEP_S + steps * RANGE_STEP_S)
        if abs(current) > FULL_SCALE_A[self.range]:
            raise MeterError(16)
        if self.range == 7 and abs(current) < UNDERLOAD_A:
            raise MeterError(32)
        self._last_current_a = current
        return current - self.offset_a

    def _measured(self, value: float) -> str:
        self._last_answer = value
        return number(value)

    def _current(self) -> str:
        return self._measured(self._measure())

    def _value(self) -> str:
        """The calibrated value: amperes with `SD-1`, else × the head's factor (lx per A)."""
        factor = 1.0 if self.calibration_entry == -1 else 1.0 / self.responsivity_a_per_lx
        return self._measured(self._measure() * factor)

    def _voltage(self) -> str:
        """The current amplifier's output: ±2 V at full scale of the present range."""
        return self._measured(self._measure() / FULL_SCALE_A[self.range] * 2.0)

    def _peak(self, sign: int) -> float:
        """Max (+1) or min (−1) ADC sample of the last measurement: ±3 σ of the noise around it."""
        return self._last_answer + sign * 3.0 * self.world.config.simulation.meter_noise_rel * abs(self._last_answer)

    def _percent_of_range(self) -> str:
        return f"{100.0 * abs(self._last_current_a) / FULL_SCALE_A[self.range]:+05.1f}"

    # -- settings (no answer) and parameter read-backs ----------------------------------------
    def _autorange(self, p: str) -> None:
        self.autorange = integer(p, 0, 1) == 1

    def _set_range(self, p: str) -> None:
        self.range = integer(p, 0, 7)

    def _integration(self, p: str) -> None:
        self.integration_steps = integer(p, 1, 59999)

    def _offset(self, p: str) -> None:
        self.offset_a = self._last_current_a if integer(p, 0, 1) == 1 else 0.0

    def _calibration(self, p: str) -> None:
        self.calibration_entry = integer(p, -2, 249)

    def _wavelength(self, p: str) -> None:
        self.wavelength_nm = integer(p, 0, 99999)

    def _sync(self, p: str) -> None:
        self.sync = integer(p, 0, 1) == 1

    def _acknowledge(self, p: str) -> None:
        self.acknowledge_chars = integer(p, 0, 1) == 1

    def _parameter(self, p: str) -> str:
        """`GS0` … `GS7`: autorange, range, offset, integration time, factor, entry, wavelength, bits."""
        return (str(int(self.autorange)), str(self.range), number(self.offset_a), str(self.integration_steps),
                number(1.0 / self.responsivity_a_per_lx), str(self.calibration_entry), str(self.wavelength_nm),
                str(int(self.sync) << 1))[integer(p, 0, 7)]
