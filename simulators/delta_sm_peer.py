"""Protocol peer of a Delta Elektronika SM15K (or an SM supply with a PSC-ETH module) on loopback TCP.

Written from the manual "Ethernet & Sequencer Programming SM15K" (rev. July
2021), not from our driver. Raw TCP, one LF-terminated line per command, a
reply line only to queries. The peer keeps the supply's state (setpoints and
limits of voltage, current and power, positive and negative; output; CV/CC/CP
remote hand-over; remote shut-down and the interlock input; error and warning
queues; status registers A and B; communication watchdog) and drives the
filament model `world.lamp`; what does not touch the output (user data, front
panel, clock, password, calibration, Ah/Wh instruments, ...) is kept by
rig.simulators.delta_sm_system. It never sleeps: replies are immediate and rig
time passes only through the world's clock.

An erroneous command is not executed and queues an error, queries included
(they get no reply); the syntax and the codes are rig.simulators.delta_sm_scpi's.
Not modelled (answered as undefined headers): the functions (§5.9), the
Ethernet log (§5.10), interface slots (§5.11: none installed) and the sequencer
(§6). The power setpoints and limits are kept and read back but do not limit
the lamp (it never reaches them at a lamp's power); received lines end in LF
whatever `SYSTem:COMmunicate:TERminator` says (replies do end in it).

The watchdog (manual §5.6.10) counts in rig time (`world.clock`): it is
checked when a line arrives, before the line is executed, and whenever a
server loop calls `check_watchdog()`. Armed, it expires `SET` ms after the last
valid command and switches the output off; `WATchdog?` then answers `0` once
and the watchdog is off (`-1`) until it is set again.
"""

from __future__ import annotations

import math
import re
from collections import deque

from rig.simulators.delta_sm_scpi import (
    BOOLEAN,
    REMOTE_LOCAL,
    Command,
    ErrorQueue,
    ScpiError,
    choice,
    header_matches,
    integer,
    number,
    required,
    scientific,
)
from rig.simulators.delta_sm_system import TERMINATORS, SupplySystem
from rig.simulators.faults import LAMP_FAULTS
from rig.simulators.line_peer import LinePeer
from rig.simulators.world import SimWorld

#: What `inject("error_queue")` pushes: the supply reporting a fault of its own.
DEVICE_FAULT = (-300, "Device-specific error")
WATCHDOG_MIN_MS, WATCHDOG_MAX_MS = 20, 10000
#: `WATchdog TEST` loads the timer with this (s).
WATCHDOG_TEST_S = 0.0025
#: Status register A bits (manual §5.8) the peer models.
CV, CC, INTERLOCK, RSD, OUTPUT_BIT, FRONT_LOCK = 1, 2, 2048, 4096, 8192, 16384
#: Status register B: which setpoints are programmed remotely.
REM_BITS = {"CV": 1, "CC": 2, "CP": 4}
#: An SM15K delivers at most 15 kW.
MAX_POWER_W = 15000.0
#: The received lines kept for inspection (`received`), newest last.
RECEIVED_LOG = 1000
MODEL = re.compile(r"SM(\d+(?:\.\d+)?)-CP-(\d+(?:\.\d+)?)")
WATCHDOG = ("SYSTem", "COMmunicate", "WATchdog")
#: (setpoint and limit name, unit, the mode whose remote hand-over programs it, the sign of its range)
QUANTITIES = {"V": ("VOLtage", "CV", 1), "A": ("CURrent", "CC", 1), "A-": ("CURrent", "CC", -1),
              "W": ("POWer", "CP", 1), "W-": ("POWer", "CP", -1)}


class DeltaSMPeer(LinePeer):
    """Simulated SM15K whose load is `world.lamp`; powers up at 0 V, 0 A, output off, front-panel control,
    limits at the maxima (disabled), watchdog off, remote shut-down off, interlock closed.

    `model` `SM<V>-CP-<A>` (the manual's example is an `SM500-CP-90`) gives the maxima unless they are given;
    without either it is a 15 V / 10 A supply, as a 12 V lamp's would be."""

    FAULTS = LAMP_FAULTS

    def __init__(self, world: SimWorld, *, max_voltage_v: float | None = None, max_current_a: float | None = None,
                 model: str | None = None, serial: str = "000000000001", firmware: str = "SIM_P0150"):
        super().__init__("tcp")
        self.world = world
        rated = MODEL.fullmatch(model or "")
        self.max_voltage_v = max_voltage_v or (float(rated.group(1)) if rated else 15.0)
        self.max_current_a = max_current_a or (float(rated.group(2)) if rated else 10.0)
        self.max_power_w = min(self.max_voltage_v * self.max_current_a, MAX_POWER_W)
        self.maxima = {"V": self.max_voltage_v, "A": self.max_current_a, "W": self.max_power_w}
        model = model or f"SM{self.max_voltage_v:g}-CP-{self.max_current_a:g}"
        self.identity = f"DELTA ELEKTRONIKA BV,{model},{serial},{firmware},0"
        self.remote = {"CV": False, "CC": False, "CP": False}
        self.errors, self.warnings = ErrorQueue(), ErrorQueue()
        self.setpoints = dict.fromkeys(QUANTITIES, 0.0)
        self.output_on = False
        self.rsd = False
        self.interlock_open = False
        #: The limits as set (value, enabled); a disabled limit is the maximum.
        self.limits = {q: (self._maximum(q), False) for q in QUANTITIES}
        self.watchdog_ms: int | None = None          # the last SET, for SET?
        self.watchdog_armed = False
        self.watchdog_timed_out = False
        self._watchdog_due = math.inf
        #: The lines received, decoded (undecodable bytes replaced), newest last.
        self.received: deque[str] = deque(maxlen=RECEIVED_LOG)
        lamp = world.lamp
        self.system = SupplySystem(world.clock, self.max_voltage_v, self.max_current_a, self._measured_current,
                                   self._measured_power)
        self._commands: list[Command] = [
            *[((("SOURce", name, "NEGative") if sign < 0 else ("SOURce", name)),
               lambda p, q=q: self._set_setpoint(q, p), lambda q=q: f"{self.setpoints[q]:.4f}")
              for q, (name, _, sign) in QUANTITIES.items()],
            *[((("SOURce", name, "NEGative", "MAXimum") if sign < 0 else ("SOURce", name, "MAXimum")), None,
               lambda q=q: f"{self._maximum(q):g}") for q, (name, _, sign) in QUANTITIES.items()],
            *[(("SOURce", name, "STEpsize"), None, lambda q=q: scientific(self.maxima[q] / 65535))
              for q, name in (("V", "VOLtage"), ("A", "CURrent"), ("W", "POWer"))],
            *[((("SYSTem", "LIMits", name, "NEGative") if sign < 0 else ("SYSTem", "LIMits", name)),
               lambda p, q=q: self._set_limit(q, p), lambda q=q: f"{self.limits[q][0]:.4f}")
              for q, (name, _, sign) in QUANTITIES.items()],
            (("MEASure", "VOLtage"), None, lambda: f"{self.system.measured('VOL', lamp.voltage_v()):.4f}"),
            (("MEASure", "CURrent"), None, lambda: f"{self._measured_current():.4f}"),
            (("MEASure", "POWer"), None, lambda: f"{self._measured_power():.2f}"),
            (("OUTPut",), lambda p: self._switch(choice(p, BOOLEAN)), lambda: str(int(self.output_on))),
            (("SYSTem", "RSD", "[STAtus]"), self._set_rsd, lambda: str(int(self.rsd))),
            (("STATus", "REGister", "A"), None, self._register_a),
            (("STATus", "REGister", "B"), None,
             lambda: str(sum(bit for mode, bit in REM_BITS.items() if self.remote[mode]))),
            *[(("SYSTem", "REMote", mode, "[STAtus]"), lambda p, m=mode: self._set_remote(m, p),
               lambda m=mode: "REMote" if self.remote[m] else "LOCal") for mode in REM_BITS],
            (WATCHDOG, self._watchdog_command, self._watchdog_state),
            (("SYSTem", "ERRor"), None, self.errors.pop),
            (("SYSTem", "WARning"), None, self.warnings.pop),
            (("*IDN",), None, lambda: self.identity),
            (("*RST",), lambda p: self._reset(), None),
            (("*CLS",), lambda p: self.errors.clear(), None),
            *self.system.commands(),
        ]
        self._program()

    def inject(self, fault: str, count: int = 1) -> None:
        """Reply faults spoil the next `count` replies; `error_queue` queues `count` entries; `burnout` now."""
        self.FAULTS.check(fault, count)
        if fault == "error_queue":
            with self._lock:
                for _ in range(count):
                    self.errors.push(*DEVICE_FAULT)
        elif fault == "burnout":
            self.world.lamp.burn_out()
        else:
            super().inject(fault, count)

    def set_interlock(self, open_: bool) -> None:
        """The interlock input (rear connector) opened or closed: while open the output feeds nothing."""
        with self._lock:
            self.interlock_open = open_
            self._feed()

    def warn(self, message: str) -> None:
        """The supply has a warning to report (`SYSTem:WARning?`); the manual publishes no list of them."""
        with self._lock:
            self.warnings.push(301, message)

    # -- protocol -----------------------------------------------------------------------------
    def respond(self, line: bytes) -> bytes | None:
        """The reply as it goes on the wire, after any injected fault (only replies take one)."""
        reply = self.answer(line)
        return None if reply is None else self.wire(reply, self.take_fault())

    def wire(self, reply: str, fault: str | None) -> bytes | None:
        """The reply ends in the terminator `SYSTem:COMmunicate:TERminator` chose (LF after power-on)."""
        data = super().wire(reply, fault)
        if data is None or not data.endswith(b"\n"):
            return data
        return data[:-1] + TERMINATORS[self.system.terminator]

    def overlong(self) -> bytes | None:
        """A line longer than the peer takes was dropped: an error, as for any command it cannot execute."""
        with self._lock:
            self.errors.push(-223, "Too much data")
        return None

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

    def answer(self, line: bytes) -> str | None:
        """Execute one line (terminator stripped); the reply line, or None for settings and errors."""
        with self._lock:
            self.received.append(line.decode("ascii", "replace"))
            self._expire_watchdog()                  # the line arrives now: was it too late?
            try:
                return self._execute(line)
            except ScpiError as err:
                self.errors.push(err.code, err.message)
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
            if not header_matches(tokens, mnemonics):
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

    # -- setpoints, limits, output ----------------------------------------------------------------
    @property
    def voltage_v(self) -> float:
        return self.setpoints["V"]

    @property
    def current_a(self) -> float:
        return self.setpoints["A"]

    def _maximum(self, quantity: str) -> float:
        """The positive or negative maximum (the simulated supply sinks as much as it sources)."""
        return QUANTITIES[quantity][2] * self.maxima[quantity.rstrip("-")]

    def _reset(self) -> None:
        """`*RST` (manual table 5.1): setpoints 0, RSD off, CV/CC/CP programmed remotely, front panel unlocked;
        output, limits, watchdog kept."""
        self.setpoints = dict.fromkeys(QUANTITIES, 0.0)
        self.rsd = False
        self.remote = dict.fromkeys(REM_BITS, True)
        self.system.reset()
        self._program()
        self._feed()

    def _bound(self, quantity: str) -> float:
        value, enabled = self.limits[quantity]
        return value if enabled else self._maximum(quantity)

    def _set_setpoint(self, quantity: str, param: str) -> None:
        """Within 0 … the limit (or maximum), on the side of the quantity's sign, and programmed remotely."""
        bound = self._bound(quantity)
        value = number(param, min(0.0, bound), max(0.0, bound))
        if not self.remote[QUANTITIES[quantity][1]]:
            raise ScpiError(-221, "Settings conflict")      # the front panel has this setpoint
        self.setpoints[quantity] = value
        self._program()

    def _set_limit(self, quantity: str, param: str) -> None:
        """`<NR2>,<boolean>`: the limit and whether it is enabled; a setpoint beyond a new enabled limit is
        brought to it (the manual does not say what the supply does; this keeps the limit true)."""
        value_text, comma, flag = param.partition(",")
        maximum = self._maximum(quantity)
        value = number(value_text, min(0.0, maximum), max(0.0, maximum))
        enabled = choice(flag.strip() if comma else "", BOOLEAN)
        self.limits[quantity] = (value, enabled)
        bound = self._bound(quantity)
        setpoint = self.setpoints[quantity]
        self.setpoints[quantity] = min(setpoint, bound) if bound >= 0 else max(setpoint, bound)
        self._program()

    def _program(self) -> None:
        """The lamp sees the voltage and current setpoints."""
        self.world.lamp.set_compliance(self.setpoints["V"])
        self.world.lamp.set_current(self.setpoints["A"])

    def _feed(self) -> None:
        """The lamp gets power only while the output is on, remote shut-down off and the interlock closed."""
        delivering = self.output_on and not self.rsd and not self.interlock_open
        if self.world.lamp.output_on != delivering:
            self.world.lamp.switch(delivering)

    def _switch(self, on: bool) -> None:
        self.output_on = on
        self._feed()

    def _set_rsd(self, param: str) -> None:
        self.rsd = choice(param, BOOLEAN)
        self._feed()

    def _set_remote(self, mode: str, param: str) -> None:
        self.remote[mode] = choice(param, REMOTE_LOCAL)

    def _measured_current(self) -> float:
        return self.system.measured("CUR", self.world.lamp.filament_current_a())

    def _measured_power(self) -> float:
        return self.system.measured("VOL", self.world.lamp.voltage_v()) * self._measured_current()

    def _register_a(self) -> str:
        """Status register A as a decimal: CV or CC while the output feeds the lamp (CV when the voltage setpoint
        limits it, an open filament included), Interlock, RSD, Output, Front-panel lock. Limit, fail and
        temperature bits are not modelled."""
        lamp = self.world.lamp
        bits = (INTERLOCK * self.interlock_open | RSD * self.rsd | OUTPUT_BIT * self.output_on
                | FRONT_LOCK * self.system.front_locked)
        if lamp.output_on:
            bits |= CV if lamp.voltage_v() >= self.setpoints["V"] - 1e-9 else CC
        return str(bits)

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
        action = required(action).upper()
        if action == "SET?" and not value:
            return str(self.watchdog_ms if self.watchdog_armed else -1)
        if action == "SET":
            self.watchdog_ms = integer(value, WATCHDOG_MIN_MS, WATCHDOG_MAX_MS)
            self.watchdog_armed, self.watchdog_timed_out = True, False
            self._restart_watchdog()
        elif action == "STOP" and not value:
            self.watchdog_armed = self.watchdog_timed_out = False
        elif action == "TEST" and not value:
            self.watchdog_armed, self.watchdog_timed_out = True, False
            self._watchdog_due = self.world.clock.now() + WATCHDOG_TEST_S
        else:
            raise ScpiError(-224, "Illegal parameter value")
        return None
