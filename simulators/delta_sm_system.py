"""What an SM15K keeps besides its output: user data, front panel, clock, password, terminator, measurement
calibration, power-sink reactions and the Ah/Wh instruments — the manual's §5.1.2–3, §5.3.5, §5.4, §5.5 and
§5.6.3–11, for the protocol peer (rig.simulators.delta_sm_peer), which owns the output and the lamp.

Replies follow the manual where it gives a format; where it does not, the choice is named here (and in
docs/sm15k.md): booleans read back as `0`/`1`, calibration values with 6 digits, temperatures with 1 decimal.
"""

from __future__ import annotations

import re
from collections.abc import Callable

from rig.core.clock import Clock
from rig.simulators.delta_sm_scpi import (
    BOOLEAN,
    Command,
    ScpiError,
    arguments,
    choice,
    integer,
    number,
    required,
    scientific,
)

#: `*PUD` data: A-Z, a-z, 0-9, space, _ and -, 72 at most (§5.1.2).
PUD = re.compile(r"[A-Za-z0-9 _-]{0,72}")
INSTRUMENT_STATES = ("OFF", "ON", "SUSPEND", "RESUME")
TERMINATORS = {"LF": b"\n", "CR": b"\r", "CRLF": b"\r\n"}
#: The supply's internal temperature (°C) with no load, and its rise per W delivered (a model).
AMBIENT_C, RISE_C_PER_W = 30.0, 0.01


class Instrument:
    """The Ah or Wh instrument (§5.3.5): totals and extremes of positive current (power) while enabled, sampled
    at each query (the supply samples every 100 ms; between queries the load is taken as constant)."""

    def __init__(self, clock: Clock, sample: Callable[[], float], digits: int):
        self.clock, self.sample, self.digits = clock, sample, digits
        self.state = "OFF"
        self._reset()

    def _reset(self) -> None:
        self.active_s = self.total = 0.0
        self.low = self.high = 0.0
        self._seen = False
        self._last = self.clock.now()

    def _advance(self) -> None:
        now = self.clock.now()
        if self.state in ("ON", "RESUME"):
            value = self.sample()
            self.active_s += now - self._last
            self.total += value * (now - self._last) / 3600
            self.low, self.high = (min(self.low, value), max(self.high, value)) if self._seen else (value, value)
            self._seen = True
        self._last = now

    def command(self, param: str) -> str | None:
        """`STATE,<setting>` or one of the queries `STATE?`, `TIMEHR?`, `TIMESEC?`, `POS|NEG,TOTAL?|…MIN?|…MAX?`."""
        self._advance()
        what = [p.strip().upper() for p in required(param).split(",")]
        if what[0] == "STATE" and len(what) == 2 and what[1] in INSTRUMENT_STATES:
            if what[1] == "ON":
                self._reset()
            self.state = what[1]
            return None
        enabled = self.state != "OFF"
        queries = {("STATE?",): self.state, ("TIMEHR?",): f"{self.active_s / 3600 if enabled else 0:.3f}",
                   ("TIMESEC?",): f"{self.active_s if enabled else 0:.1f}",
                   ("POS", "TOTAL?"): scientific(self.total if enabled else 0.0), ("NEG", "TOTAL?"): scientific(0.0)}
        for side, extreme, value in (("POS", "MIN?", self.low), ("POS", "MAX?", self.high), ("NEG", "MIN?", 0.0),
                                     ("NEG", "MAX?", 0.0)):
            for letter in "IP":
                queries[(side, letter + extreme)] = f"{value if enabled else 0.0:.{self.digits}f}"
        reply = queries.get(tuple(what))
        if reply is None:
            raise ScpiError(-224, "Illegal parameter value")
        return reply


class SupplySystem:
    """The bookkeeping settings of one SM15K and the commands that read and set them."""

    def __init__(self, clock: Clock, max_voltage_v: float, max_current_a: float, measure_current_a: Callable[[], float],
                 measure_power_w: Callable[[], float]):
        self.clock = clock
        self.max = {"VOL": max_voltage_v, "CUR": max_current_a}
        self.power_w = measure_power_w
        self.pud = ""
        self.password = ""                              # "" : none set
        self.front_locked = False
        self.front_controls = False
        self.terminator = "LF"
        self.calibration = {(q, k): 1.0 if k == "GAIn" else 0.0 for q in ("VOL", "CUR") for k in ("GAIn", "OFFset")}
        self.power_sink = {"RSD": True, "INTERLOCK": True, "OUTPUT": True}
        self._clock_offset_s: float | None = None       # wall-clock time of day minus rig time, once set
        self._date: tuple[int, int, int] | None = None
        self.instruments = {"AH": Instrument(clock, measure_current_a, 4), "WH": Instrument(clock, measure_power_w, 2)}

    def reset(self) -> None:
        """`*RST` (table 5.1): the front panel unlocked."""
        self.front_locked = False

    def measured(self, quantity: str, raw: float) -> float:
        """A measurement through the calibration (§5.4): raw × gain + offset."""
        return raw * self.calibration[(quantity, "GAIn")] + self.calibration[(quantity, "OFFset")]

    def commands(self) -> list[Command]:
        flag = {True: "1", False: "0"}
        cal: list[Command] = [(("CALIbrate", q, "MEAsure", k), self._calibrate(q, k), self._calibration(q, k))
                              for q in ("VOLtage", "CURrent") for k in ("GAIn", "OFFset")]
        return [
            (("*PUD",), self._set_pud, lambda: self.pud),
            (("*SAV",), self._save, None),
            (("SYSTem", "FROntpanel", "HIGhlight"), lambda p: None, None),
            (("SYSTem", "FROntpanel", "[STAtus]"), lambda p: self._flag("front_locked", p),
             lambda: flag[self.front_locked]),
            (("SYSTem", "FROntpanel", "CONtrols"), lambda p: self._flag("front_controls", p),
             lambda: flag[self.front_controls]),
            (("SYSTem", "TIMe"), self._set_time, self._time),
            (("SYSTem", "DATe"), self._set_date, self._date_text),
            (("SYSTem", "PASsword"), self._set_password, None),
            (("SYSTem", "PASsword", "STAtus"), None, lambda: flag[bool(self.password)]),
            (("SYSTem", "COMmunicate", "TERminator"), self._set_terminator, lambda: self.terminator),
            (("SYSTem", "POWersink"), self._power_sink, None),
            (("MEASure", "INStrument"), self._instrument, None),
            (("MEASure", "TEMperature"), None, lambda: f"{AMBIENT_C + RISE_C_PER_W * self.power_w():.1f}"),
            *cal,
        ]

    # -- settings -------------------------------------------------------------------------------
    def _set_pud(self, param: str) -> None:
        if not PUD.fullmatch(param):
            raise ScpiError(-224, "Illegal parameter value")
        self.pud = param

    def _save(self, param: str) -> None:
        """`*SAV`, or `*SAV <password>` when one is set (nothing persists beyond the peer's life)."""
        if param != self.password:
            raise ScpiError(-221, "Settings conflict")

    def _flag(self, name: str, param: str) -> None:
        setattr(self, name, choice(param, BOOLEAN))

    def _set_time(self, param: str) -> None:
        hour, minute, second = (integer(p, 0, high) for p, high in zip(arguments(param, 3), (23, 59, 59), strict=True))
        self._clock_offset_s = hour * 3600 + minute * 60 + second - self.clock.now()

    def _time(self) -> str:
        if self._clock_offset_s is None:
            return "UNKNOWN"
        seconds = int(self.clock.now() + self._clock_offset_s) % 86400
        return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"

    def _set_date(self, param: str) -> None:
        year, month, day = (integer(p, low, high) for p, (low, high) in
                            zip(arguments(param, 3), ((2019, 2099), (1, 12), (1, 31)), strict=True))
        self._date = (year, month, day)

    def _date_text(self) -> str:
        return "UNKNOWN" if self._date is None else "{}-{}-{}".format(*self._date)

    def _set_password(self, param: str) -> None:
        """`<old>,<new>`: `DEFAULT` stands for no password, as old or new (§5.6.9); at most 9 characters."""
        old, new = arguments(param, 2)
        if (old.upper() == "DEFAULT") != (not self.password) or (self.password and old != self.password):
            raise ScpiError(-221, "Settings conflict")
        if len(new) > 9 or not new:
            raise ScpiError(-224, "Illegal parameter value")
        self.password = "" if new.upper() == "DEFAULT" else new

    def _set_terminator(self, param: str) -> None:
        value = required(param).upper()
        if value not in TERMINATORS:
            raise ScpiError(-224, "Illegal parameter value")
        self.terminator = value

    def _power_sink(self, param: str) -> str | None:
        """`rsd|interlock|output,<boolean>` or `…?` (§5.5): whether the power sink reacts to it (1)."""
        what, _, value = required(param).partition(",")
        key = what.strip().upper().removesuffix("?")
        if key not in self.power_sink:
            raise ScpiError(-224, "Illegal parameter value")
        if what.strip().endswith("?") and not value:
            return "1" if self.power_sink[key] else "0"
        self.power_sink[key] = choice(value.strip(), BOOLEAN)
        return None

    def _instrument(self, param: str) -> str | None:
        kind, _, rest = required(param).partition(",")
        instrument = self.instruments.get(kind.strip().upper())
        if instrument is None:
            raise ScpiError(-224, "Illegal parameter value")
        return instrument.command(rest)

    def _calibration(self, quantity: str, kind: str) -> Callable[[], str]:
        return lambda: f"{self.calibration[(quantity[:3].upper(), kind)]:.6f}"

    def _calibrate(self, quantity: str, kind: str) -> Callable[[str], None]:
        """Gain 0.9 … 1.1, offset within about 1/30 of the maximum (§5.4.5)."""
        key = (quantity[:3].upper(), kind)

        def set_value(param: str) -> None:
            bound = self.max[key[0]] / 30
            self.calibration[key] = number(param, 0.9, 1.1) if kind == "GAIn" else number(param, -bound, bound)
        return set_value
