"""Protocol peer of a Delta Elektronika SM15K (or an SM supply with a PSC-ETH module) on loopback TCP.

Written from the manual "Ethernet & Sequencer Programming SM15K" (rev. July
2021), not from our driver. Raw TCP, one LF-terminated line per command, a
reply line only to queries. The peer keeps the supply's state (setpoints,
limits, output, CV/CC remote hand-over, error queue, communication watchdog)
and drives the filament model `world.lamp`. It never sleeps: replies are
immediate and rig time passes only through the world's clock.

Parsing follows SCPI: headers separated by `:`, any case, each keyword in its
long form, its short form (the capitals) or anything in between (`CURR`);
`[STAtus]` nodes may be left out. An erroneous command is not executed and
queues an error, queries included (they get no reply). The manual publishes no
error list: the codes here are SCPI's, and a client must not rely on them.

The watchdog (manual §5.6.10) counts in rig time (`world.clock`): it is
checked when a line arrives, before the line is executed, and whenever a
server loop calls `check_watchdog()`. Armed, it expires `SET` ms after the last
valid command and switches the output off; `WATchdog?` then answers `0` once
and the watchdog is off (`-1`) until it is set again.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable

from rig.simulators.faults import LAMP_FAULTS
from rig.simulators.line_peer import LinePeer
from rig.simulators.world import SimWorld

ERROR_QUEUE_SIZE = 10
NO_ERROR = "0,None"
#: What `inject("error_queue")` pushes: the supply reporting a fault of its own.
DEVICE_FAULT = (-300, "Device-specific error")
WATCHDOG_MIN_MS, WATCHDOG_MAX_MS = 20, 10000
#: `WATchdog TEST` loads the timer with this (s).
WATCHDOG_TEST_S = 0.0025
#: STATus:REGister:A bits (manual §5.8).
CV, CC, OUTPUT_BIT = 1, 2, 8192


class ScpiError(Exception):
    """A command the supply refuses: queued as `code,message`."""

    def __init__(self, code: int, message: str):
        super().__init__(f"{code},{message}")
        self.code = code
        self.message = message


def keyword_matches(token: str, mnemonic: str) -> bool:
    """`token` names `mnemonic` (e.g. `VOLtage`): at least its capitals, at most its long form, any case."""
    short = "".join(c for c in mnemonic if not c.islower())
    token, long = token.upper(), mnemonic.upper()
    return long.startswith(token) and token.startswith(short)


def _required(param: str) -> str:
    if not param:
        raise ScpiError(-109, "Missing parameter")
    return param


def _number(param: str) -> float:
    try:
        value = float(_required(param))
    except ValueError:
        raise ScpiError(-104, "Data type error") from None
    if not math.isfinite(value):
        raise ScpiError(-104, "Data type error")
    return value


def _choice(param: str, choices: dict[str, bool]) -> bool:
    _required(param)
    for mnemonic, value in choices.items():
        if keyword_matches(param, mnemonic):
            return value
    raise ScpiError(-224, "Illegal parameter value")


#: A setting: the parameter text → None, or a reply (`WATchdog SET?` is a query written as a parameter).
Setter = Callable[[str], str | None]
Getter = Callable[[], str]
BOOLEAN = {"ON": True, "OFF": False, "1": True, "0": False}
REMOTE_LOCAL = {"REMote": True, "LOCal": False}
WATCHDOG = ("SYSTem", "COMmunicate", "WATchdog")


class DeltaSMPeer(LinePeer):
    """Simulated SM15K whose load is `world.lamp`; powers up at 0 V, 0 A, output off, front-panel control,
    limits at the maxima (disabled), watchdog off."""

    FAULTS = LAMP_FAULTS

    def __init__(self, world: SimWorld, *, max_voltage_v: float = 15.0, max_current_a: float = 10.0,
                 model: str | None = None, serial: str = "000000000001", firmware: str = "SIM_P0150"):
        super().__init__("tcp")
        self.world = world
        self.max_voltage_v = max_voltage_v
        self.max_current_a = max_current_a
        model = model or f"SM{max_voltage_v:g}-CP-{max_current_a:g}"
        self.identity = f"DELTA ELEKTRONIKA BV,{model},{serial},{firmware},0"
        self.remote = {"CV": False, "CC": False}
        self.errors: deque[tuple[int, str]] = deque()
        self.voltage_v = self.current_a = 0.0
        self.output_on = False
        #: The limits as set (value, enabled); a disabled limit is the maximum.
        self.limits = {"V": (max_voltage_v, False), "A": (max_current_a, False)}
        self.watchdog_ms: int | None = None          # the last SET, for SET?
        self.watchdog_armed = False
        self.watchdog_timed_out = False
        self._watchdog_due = math.inf
        #: (keywords, setter(parameter), getter() -> reply); None where the form does not exist.
        self._commands: list[tuple[tuple[str, ...], Setter | None, Getter | None]] = [
            (("SOURce", "VOLtage"), self._set_voltage, lambda: f"{self.voltage_v:.4f}"),
            (("SOURce", "CURrent"), self._set_current, lambda: f"{self.current_a:.4f}"),
            (("SOURce", "VOLtage", "MAXimum"), None, lambda: f"{self.max_voltage_v:g}"),   # max values: integers
            (("SOURce", "CURrent", "MAXimum"), None, lambda: f"{self.max_current_a:g}"),
            (("SYSTem", "LIMits", "VOLtage"), lambda p: self._set_limit("V", p), lambda: self._limit("V")),
            (("SYSTem", "LIMits", "CURrent"), lambda p: self._set_limit("A", p), lambda: self._limit("A")),
            (("MEASure", "VOLtage"), None, lambda: f"{self.world.lamp.voltage_v():.4f}"),
            (("MEASure", "CURrent"), None, lambda: f"{self.world.lamp.filament_current_a():.4f}"),
            (("MEASure", "POWer"), None,
             lambda: f"{self.world.lamp.voltage_v() * self.world.lamp.filament_current_a():.2f}"),
            (("OUTPut",), self._set_output, lambda: str(int(self.output_on))),
            (("STATus", "REGister", "A"), None, self._register_a),
            (("SYSTem", "REMote", "CV", "[STAtus]"), lambda p: self._set_remote("CV", p),
             lambda: self._remote_state("CV")),
            (("SYSTem", "REMote", "CC", "[STAtus]"), lambda p: self._set_remote("CC", p),
             lambda: self._remote_state("CC")),
            (WATCHDOG, self._watchdog_command, self._watchdog_state),
            (("SYSTem", "ERRor"), None, self._pop_error),
            (("*IDN",), None, lambda: self.identity),
            (("*RST",), lambda p: self._reset(), None),
            (("*CLS",), lambda p: self.errors.clear(), None),
        ]
        self._set_setpoints(0.0, 0.0)

    def inject(self, fault: str, count: int = 1) -> None:
        """Reply faults spoil the next `count` replies; `error_queue` queues `count` entries; `burnout` now."""
        self.FAULTS.check(fault, count)
        if fault == "error_queue":
            with self._lock:
                for _ in range(count):
                    self._push_error(*DEVICE_FAULT)
        elif fault == "burnout":
            self.world.lamp.burn_out()
        else:
            super().inject(fault, count)

    # -- protocol -----------------------------------------------------------------------------
    def respond(self, line: bytes) -> bytes | None:
        """The reply as it goes on the wire, after any injected fault (only replies take one)."""
        reply = self.answer(line)
        return None if reply is None else self.wire(reply, self.take_fault())

    def check_watchdog(self) -> str | None:
        """Let an armed watchdog expire if its time is up (a served rig's loop calls this between lines);
        what happened, for the server's log, if it expired now."""
        with self._lock:
            set_s = (self.watchdog_ms or 0) / 1000
            last_command_s = self._watchdog_due - set_s
            if not self._expire_watchdog():
                return None
            now = self.world.clock.now()
            return (f"lamp output switched off by the communication watchdog at rig time {now:.3f} s, "
                    f"{now - last_command_s:.3f} s after the last command (watchdog {set_s:g} s)")

    # -- SCPI ------------------------------------------------------------------------------
    def answer(self, line: bytes) -> str | None:
        """Execute one line (terminator stripped); the reply line, or None for settings and errors."""
        with self._lock:
            self._expire_watchdog()                  # the line arrives now: was it too late?
            try:
                return self._execute(line)
            except ScpiError as err:
                self._push_error(err.code, err.message)
                return None

    def _execute(self, line: bytes) -> str | None:
        try:
            text = line.decode("ascii").strip()
        except UnicodeDecodeError:
            raise ScpiError(-102, "Syntax error") from None
        if not text:
            return None
        header, _, param = text.partition(" ")
        param = param.strip()
        query = header.endswith("?")
        tokens = header.removesuffix("?").removeprefix(":").split(":")
        for mnemonics, setter, getter in self._commands:
            if not self._matches(tokens, mnemonics):
                continue
            if query and getter is not None:
                if param:
                    raise ScpiError(-108, "Parameter not allowed")
                reply: str | None = getter()
            elif not query and setter is not None:
                reply = setter(param)
            else:
                continue
            if mnemonics != WATCHDOG:                # those restart (or stop) it themselves
                self._restart_watchdog()
            return reply
        raise ScpiError(-113, "Undefined header")

    @staticmethod
    def _matches(tokens: list[str], mnemonics: tuple[str, ...]) -> bool:
        """The header names the command, with or without its optional (`[...]`) last node."""
        forms = [mnemonics]
        if mnemonics[-1].startswith("["):
            forms = [mnemonics[:-1], (*mnemonics[:-1], mnemonics[-1].strip("[]"))]
        return any(len(tokens) == len(form) and all(map(keyword_matches, tokens, form)) for form in forms)

    def _push_error(self, code: int, message: str) -> None:
        if len(self.errors) >= ERROR_QUEUE_SIZE:
            self.errors[-1] = (-350, "Queue overflow")
        else:
            self.errors.append((code, message))

    def _pop_error(self) -> str:
        if not self.errors:
            return NO_ERROR
        code, message = self.errors.popleft()
        return f"{code},{message}"

    # -- setpoints, limits, output ----------------------------------------------------------------
    def _reset(self) -> None:
        """`*RST` (manual table 5.1): set points 0, CV/CC programmed remotely; output, limits, watchdog kept."""
        self._set_setpoints(0.0, 0.0)
        self.remote = {"CV": True, "CC": True}

    def _set_setpoints(self, voltage_v: float, current_a: float) -> None:
        self.voltage_v, self.current_a = voltage_v, current_a
        self.world.lamp.set_compliance(voltage_v)
        self.world.lamp.set_current(current_a)

    def _bound(self, quantity: str) -> float:
        value, enabled = self.limits[quantity]
        return value if enabled else (self.max_voltage_v if quantity == "V" else self.max_current_a)

    def _setpoint(self, param: str, quantity: str, mode: str) -> float:
        value = _number(param)
        if not 0.0 <= value <= self._bound(quantity):
            raise ScpiError(-222, "Data out of range")
        if not self.remote[mode]:
            raise ScpiError(-221, "Settings conflict")      # the front panel has this setpoint
        return value

    def _set_voltage(self, param: str) -> None:
        self._set_setpoints(self._setpoint(param, "V", "CV"), self.current_a)

    def _set_current(self, param: str) -> None:
        self._set_setpoints(self.voltage_v, self._setpoint(param, "A", "CC"))

    def _set_limit(self, quantity: str, param: str) -> None:
        """`<NR2>,<boolean>`: the limit and whether it is enabled; a setpoint above a new enabled limit is
        lowered to it (the manual does not say what the supply does; this keeps the limit true)."""
        value_text, comma, flag = param.partition(",")
        value = _number(value_text)
        enabled = _choice(flag.strip() if comma else "", BOOLEAN)
        maximum = self.max_voltage_v if quantity == "V" else self.max_current_a
        if not 0.0 <= value <= maximum:
            raise ScpiError(-222, "Data out of range")
        self.limits[quantity] = (value, enabled)
        self._set_setpoints(min(self.voltage_v, self._bound("V")), min(self.current_a, self._bound("A")))

    def _limit(self, quantity: str) -> str:
        """The manual gives no reply format; clients read it as a number (four digits, like the setpoints)."""
        return f"{self.limits[quantity][0]:.4f}"

    def _set_output(self, param: str) -> None:
        self._switch(_choice(param, BOOLEAN))

    def _switch(self, on: bool) -> None:
        self.output_on = on
        self.world.lamp.switch(on)

    def _set_remote(self, mode: str, param: str) -> None:
        self.remote[mode] = _choice(param, REMOTE_LOCAL)

    def _remote_state(self, mode: str) -> str:
        return "REMote" if self.remote[mode] else "LOCal"

    def _register_a(self) -> str:
        """Status register A as a decimal: CV or CC (output on; CV when the voltage setpoint limits the lamp,
        an open filament included) and Output. Limit, fail and temperature bits are not modelled."""
        if not self.output_on:
            return "0"
        lamp = self.world.lamp
        at_voltage = lamp.voltage_v() >= self.voltage_v - 1e-9
        return str(OUTPUT_BIT | (CV if at_voltage else CC))

    # -- the watchdog (manual §5.6.10) ----------------------------------------------------------------
    def _expire_watchdog(self) -> bool:
        """Expire an armed watchdog whose time is up (output off); whether it did."""
        if not (self.watchdog_armed and self.world.clock.now() >= self._watchdog_due):
            return False
        self.watchdog_armed = False
        self.watchdog_timed_out = True
        self._switch(False)
        return True

    def _restart_watchdog(self) -> None:
        """Any valid command restarts an armed watchdog with its set time."""
        if self.watchdog_armed and self.watchdog_ms is not None:
            self._watchdog_due = self.world.clock.now() + self.watchdog_ms / 1000

    def _watchdog_state(self) -> str:
        """Remaining ms when the query arrived (then it restarts); `0` once after expiry (which clears the
        time-out: the watchdog is then off); `-1` off."""
        if self.watchdog_timed_out:
            self.watchdog_timed_out = False
            return "0"
        if not self.watchdog_armed:
            return "-1"
        remaining_ms = (self._watchdog_due - self.world.clock.now()) * 1000
        self._restart_watchdog()
        return str(max(1, round(remaining_ms)))

    def _watchdog_command(self, param: str) -> str | None:
        """`SET,<ms>` arms it (20 … 10000), `SET?` the set time, `STOP` disarms, `TEST` loads 2.5 ms."""
        action, _, value = param.partition(",")
        action = _required(action).upper()
        if action == "SET?" and not value:
            return str(self.watchdog_ms if self.watchdog_armed else -1)
        if action == "SET":
            try:
                ms = int(_required(value))
            except ValueError:
                raise ScpiError(-104, "Data type error") from None
            if not WATCHDOG_MIN_MS <= ms <= WATCHDOG_MAX_MS:
                raise ScpiError(-222, "Data out of range")
            self.watchdog_ms, self.watchdog_armed, self.watchdog_timed_out = ms, True, False
            self._restart_watchdog()
        elif action == "STOP" and not value:
            self.watchdog_armed = self.watchdog_timed_out = False
        elif action == "TEST" and not value:
            self.watchdog_armed, self.watchdog_timed_out = True, False
            self._watchdog_due = self.world.clock.now() + WATCHDOG_TEST_S
        else:
            raise ScpiError(-224, "Illegal parameter value")
        return None
