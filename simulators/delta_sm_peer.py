"""Protocol peer of a Delta Elektronika SM-series supply (PSC-ETH interface) on loopback TCP.

The driver talks to it exactly as to the supply's Ethernet module: raw TCP,
one LF-terminated SCPI line per command, a reply line only to queries. The
peer keeps the supply's state (setpoints, output, CV/CC remote hand-over,
error queue) and drives the filament model `world.lamp`. It never sleeps:
replies are immediate and rig time passes only through the world's clock.

Parsing follows SCPI: headers separated by `:`, any case, each keyword in its
long form, its short form (the capitals) or anything in between (`CURR`);
an erroneous command is not executed and queues an error, queries included
(they get no reply).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

from rig.simulators.faults import LAMP_FAULTS
from rig.simulators.line_peer import LinePeer
from rig.simulators.world import SimWorld

ERROR_QUEUE_SIZE = 10
NO_ERROR = "0,None"
#: What `inject("error_queue")` pushes: the supply reporting a fault of its own.
DEVICE_FAULT = (-300, "Device-specific error")


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
        return float(_required(param))
    except ValueError:
        raise ScpiError(-104, "Data type error") from None


def _choice(param: str, choices: dict[str, bool]) -> bool:
    _required(param)
    for mnemonic, value in choices.items():
        if keyword_matches(param, mnemonic):
            return value
    raise ScpiError(-224, "Illegal parameter value")


Setter = Callable[[str], None]
Getter = Callable[[], str]
ON_OFF = {"ON": True, "OFF": False, "1": True, "0": False}
REMOTE_LOCAL = {"REMote": True, "LOCal": False}


class DeltaSMPeer(LinePeer):
    """Simulated SM supply whose load is `world.lamp`; powers up at 0 V, 0 A, output off, local control."""

    FAULTS = LAMP_FAULTS

    def __init__(self, world: SimWorld, *, max_voltage_v: float = 15.0, max_current_a: float = 10.0):
        super().__init__("tcp")
        self.world = world
        self.max_voltage_v = max_voltage_v
        self.max_current_a = max_current_a
        self.identity = f"DELTA ELEKTRONIKA BV,SM{max_voltage_v:g}-{max_current_a:g},SIM0001,sim-1.0"
        self.remote = {"CV": False, "CC": False}
        self.errors: deque[tuple[int, str]] = deque()
        self.voltage_v = self.current_a = 0.0
        self.output_on = False
        #: (keywords, setter(parameter), getter() -> reply); None where the form does not exist.
        self._commands: list[tuple[tuple[str, ...], Setter | None, Getter | None]] = [
            (("SOURce", "VOLtage"), self._set_voltage, lambda: f"{self.voltage_v:.4f}"),
            (("SOURce", "CURrent"), self._set_current, lambda: f"{self.current_a:.4f}"),
            (("SOURce", "VOLtage", "MAXimum"), None, lambda: f"{self.max_voltage_v:.4f}"),
            (("SOURce", "CURrent", "MAXimum"), None, lambda: f"{self.max_current_a:.4f}"),
            (("MEASure", "VOLtage"), None, lambda: f"{self.world.lamp.voltage_v():.4f}"),
            (("MEASure", "CURrent"), None, lambda: f"{self.world.lamp.filament_current_a():.4f}"),
            (("OUTPut",), self._set_output, lambda: str(int(self.output_on))),
            (("SYSTem", "REMote", "CV"), lambda p: self._set_remote("CV", p), lambda: self._remote_state("CV")),
            (("SYSTem", "REMote", "CC"), lambda p: self._set_remote("CC", p), lambda: self._remote_state("CC")),
            (("SYSTem", "ERRor"), None, self._pop_error),
            (("*IDN",), None, lambda: self.identity),
            (("*RST",), lambda p: self._reset(), None),
            (("*CLS",), lambda p: self.errors.clear(), None),
        ]
        self._reset()

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

    # -- SCPI ------------------------------------------------------------------------------
    def answer(self, line: bytes) -> str | None:
        """Execute one line (terminator stripped); the reply line, or None for settings and errors."""
        with self._lock:
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
            if len(tokens) != len(mnemonics) or not all(map(keyword_matches, tokens, mnemonics)):
                continue
            if query and getter is not None:
                if param:
                    raise ScpiError(-108, "Parameter not allowed")
                return getter()
            if not query and setter is not None:
                setter(param)
                return None
        raise ScpiError(-113, "Undefined header")

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

    def _reset(self) -> None:
        self.voltage_v = self.current_a = 0.0
        self.output_on = False
        lamp = self.world.lamp
        lamp.set_compliance(0.0)
        lamp.set_current(0.0)
        lamp.switch(False)

    def _setpoint(self, param: str, maximum: float, mode: str) -> float:
        value = _number(param)
        if not 0.0 <= value <= maximum:
            raise ScpiError(-222, "Data out of range")
        if not self.remote[mode]:
            raise ScpiError(-221, "Settings conflict")      # the front panel has this setpoint
        return value

    def _set_voltage(self, param: str) -> None:
        self.voltage_v = self._setpoint(param, self.max_voltage_v, "CV")
        self.world.lamp.set_compliance(self.voltage_v)

    def _set_current(self, param: str) -> None:
        self.current_a = self._setpoint(param, self.max_current_a, "CC")
        self.world.lamp.set_current(self.current_a)

    def _set_output(self, param: str) -> None:
        self.output_on = _choice(param, ON_OFF)
        self.world.lamp.switch(self.output_on)

    def _set_remote(self, mode: str, param: str) -> None:
        self.remote[mode] = _choice(param, REMOTE_LOCAL)

    def _remote_state(self, mode: str) -> str:
        return "REMote" if self.remote[mode] else "LOCal"
