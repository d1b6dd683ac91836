"""Delta Elektronika SM-series DC supply (SCPI over the PSC-ETH module or a serial port) as the lamp supply.

The lamp runs in constant-current mode: on connect the driver takes over both
setpoints from the front panel (remote hand-over) and sets the voltage limit to
the supply's maximum, or a configured compliance, so the current setpoint
rules. Current changes are ramped in steps on the rig clock, because a cold
filament has about a tenth of its hot resistance (inrush).

Every setting is followed by a read of the error queue: an entry is a refusal
(persistent DeviceError naming the command and the entry). A setting and its
error read are retried together after a transient fault; settings are
absolute, so sending one twice is harmless.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import TypeVar

from rig.drivers.interfaces import LampSupply
from rig.drivers.retry import RetryPolicy, call_with_retry
from rig.drivers.transport import EventSink, LineTransport, no_events

from rig.core.clock import Clock
from rig.core.errors import DeviceError

T = TypeVar("T")

ERROR_QUEUE_SIZE = 10
#: Switching off is the safety action: it gets at least this many attempts.
OFF_ATTEMPTS = 6
#: `OUTPut?` answers 1/0 (ON/OFF on some firmware).
OUTPUT_STATES = {"1": True, "ON": True, "0": False, "OFF": False}


class DeltaSM(LampSupply):
    """`url`: `socket://host:8462` (PSC-ETH), a serial port or a pyserial URL.

    `events(kind, **fields)` hears of retries, reconnects and errors met while
    switching off; the runner points it at its log. `compliance_v` replaces
    the supply's maximum voltage as the limit.
    """

    def __init__(self, url: str, *, clock: Clock, name: str = "lamp", timeout_s: float = 1.0,
                 retry: RetryPolicy = RetryPolicy(), ramp_step_s: float = 0.1, compliance_v: float | None = None):
        if ramp_step_s <= 0:
            raise ValueError(f"ramp_step_s must be positive, got {ramp_step_s}")
        self.name = name
        self.clock = clock
        self.retry = retry
        self.ramp_step_s = ramp_step_s
        self.events: EventSink = no_events
        self._io = LineTransport(name, url, timeout_s=timeout_s)
        try:
            self._identity = self._query("*IDN?")
            self._set("*CLS")                       # stale entries would be blamed on our first setting
            self._set("SYSTem:REMote:CV REMote")
            self._set("SYSTem:REMote:CC REMote")
            self.max_current_a = self._query_float("SOURce:CURrent:MAXimum?")
            limit = self._query_float("SOURce:VOLtage:MAXimum?") if compliance_v is None else compliance_v
            self._set(f"SOURce:VOLtage {limit:.6g}")
        except BaseException:
            self._io.close()
            raise

    # -- LampSupply ----------------------------------------------------------------------------
    def identity(self) -> str:
        return self._identity

    def set_current(self, current_a: float, ramp_s: float = 0.0) -> None:
        """Staircase from the present setpoint, one step per `ramp_step_s`, the last one on target.

        A target the supply cannot reach is refused before the first step, not half-way up the ramp.
        """
        if not 0.0 <= current_a <= self.max_current_a:
            raise DeviceError(self.name, f"current {current_a:g} A outside the supply's 0 … {self.max_current_a:g} A")
        start = self._query_float("SOURce:CURrent?") if ramp_s > 0 else current_a
        steps = max(1, math.ceil(round(ramp_s / self.ramp_step_s, 9)))
        for k in range(1, steps + 1):
            self.clock.sleep(ramp_s / steps)
            self._set(f"SOURce:CURrent {start + (current_a - start) * k / steps:.6g}")

    def set_output(self, on: bool) -> None:
        if on:
            self._set("OUTPut ON")
        else:
            self._switch_off()

    def output_is_on(self) -> bool:
        return self._query("OUTPut?", _on_off)

    def measure_current_a(self) -> float:
        return self._query_float("MEASure:CURrent?")

    def measure_voltage_v(self) -> float:
        return self._query_float("MEASure:VOLtage?")

    def close(self) -> None:
        """Hand the setpoints back to the front panel (one attempt each); the output stays as it is."""
        once = replace(self.retry, attempts=1)
        try:
            for command in ("SYSTem:REMote:CV LOCal", "SYSTem:REMote:CC LOCal"):
                self._set(command, once)
        finally:
            self._io.close()

    # -- exchanges -----------------------------------------------------------------------------
    def _ask(self, command: str, parse: Callable[[str], T]) -> T:
        """One query, no retry; a reply `parse` rejects counts as garbled (transient)."""
        reply = self._io.query(command)
        try:
            return parse(reply)
        except ValueError:
            raise DeviceError(self.name, f"garbled reply to {command!r}: {reply!r}", transient=True) from None

    def _query(self, command: str, parse: Callable[[str], T] = str) -> T:
        return self._with_retry(lambda: self._ask(command, parse), command, self.retry)

    def _query_float(self, command: str) -> float:
        return self._query(command, float)

    def _set(self, command: str, policy: RetryPolicy | None = None) -> None:
        """Send a setting and read the error queue; an entry there is a refusal of this setting."""
        def exchange() -> None:
            self._io.write_line(command)
            errors = self._read_errors()
            if errors:
                raise DeviceError(self.name, f"{command!r} refused: {'; '.join(errors)}")
        self._with_retry(exchange, command, policy or self.retry)

    def _switch_off(self) -> None:
        """Safety path: more attempts, and the read-back `OUTPut?` decides, not the error queue."""
        def exchange() -> None:
            self._io.write_line("OUTPut OFF")
            errors = self._read_errors()
            if errors:
                self.events("device_errors", device=self.name, what="OUTPut OFF", errors=errors)
            if self._ask("OUTPut?", _on_off):
                raise DeviceError(self.name, "output still on after 'OUTPut OFF'", transient=True)
        policy = replace(self.retry, attempts=max(self.retry.attempts, OFF_ATTEMPTS))
        self._with_retry(exchange, "OUTPut OFF", policy)

    def _read_errors(self) -> list[str]:
        """Drain the error queue (at most its size); the entries other than `0,...`."""
        errors = []
        for _ in range(ERROR_QUEUE_SIZE):
            code, entry = self._ask("SYSTem:ERRor?", _error_entry)
            if code == 0:
                break
            errors.append(entry)
        return errors

    def _with_retry(self, action: Callable[[], T], what: str, policy: RetryPolicy) -> T:
        return call_with_retry(action, device=self.name, what=what, clock=self.clock, policy=policy,
                               on_retry=self.events, reconnect=self._io.reconnect)


def _on_off(reply: str) -> bool:
    if reply.upper() not in OUTPUT_STATES:
        raise ValueError(reply)
    return OUTPUT_STATES[reply.upper()]


def _error_entry(reply: str) -> tuple[int, str]:
    """`SYSTem:ERRor?` answers `code,text`; code 0 means the queue is empty."""
    code, comma, _ = reply.partition(",")
    if not comma:
        raise ValueError(reply)
    return int(code), reply
