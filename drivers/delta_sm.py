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
from dataclasses import replace

from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.drivers.interfaces import LampSupply
from rig.drivers.line_instrument import LineInstrument, Query, Setting, choice, number
from rig.drivers.retry import DEFAULT_RETRY, RetryPolicy
from rig.drivers.transport import PortOpener, open_pyserial

ERROR_QUEUE_SIZE = 10
#: Switching off is the safety action: it gets at least this many attempts.
OFF_ATTEMPTS = 6


def _error_entry(reply: str) -> tuple[int, str]:
    """`SYSTem:ERRor?` answers `code,text`; code 0 means the queue is empty."""
    code, comma, _ = reply.partition(",")
    if not comma:
        raise ValueError(reply)
    return int(code), reply


# -- the command table (long forms, as the manual recommends) ------------------------------------
IDENTITY = Query("*IDN?", str)
CLEAR_STATUS = Setting("*CLS")
REMOTE_CV = Setting("SYSTem:REMote:CV {}")          # REMote | LOCal: who programs the voltage
REMOTE_CC = Setting("SYSTem:REMote:CC {}")          # ... and the current
MAX_CURRENT = Query("SOURce:CURrent:MAXimum?", number, "A")
MAX_VOLTAGE = Query("SOURce:VOLtage:MAXimum?", number, "V")
VOLTAGE = Setting("SOURce:VOLtage {:.6g}", "V")
CURRENT = Setting("SOURce:CURrent {:.6g}", "A")
CURRENT_SETPOINT = Query("SOURce:CURrent?", number, "A")
OUTPUT = Setting("OUTPut {}")                        # ON | OFF
#: `OUTPut?` answers 1/0 (ON/OFF on some firmware).
OUTPUT_STATE = Query("OUTPut?", choice({"1": True, "ON": True, "0": False, "OFF": False}))
MEASURED_CURRENT = Query("MEASure:CURrent?", number, "A")
MEASURED_VOLTAGE = Query("MEASure:VOLtage?", number, "V")
ERROR = Query("SYSTem:ERRor?", _error_entry)


class DeltaSM(LineInstrument, LampSupply):
    """`url`: `socket://host:8462` (PSC-ETH), a serial port or a pyserial URL.

    `events(kind, **fields)` hears of retries, reconnects and errors met while
    switching off; the runner points it at its log. `compliance_v` replaces
    the supply's maximum voltage as the limit.
    """

    def __init__(self, url: str, *, clock: Clock, name: str = "lamp", timeout_s: float = 1.0,
                 retry: RetryPolicy = DEFAULT_RETRY, ramp_step_s: float = 0.1, compliance_v: float | None = None,
                 open_port: PortOpener = open_pyserial):
        if ramp_step_s <= 0:
            raise ValueError(f"ramp_step_s must be positive, got {ramp_step_s}")
        super().__init__(url, name=name, clock=clock, timeout_s=timeout_s, retry=retry, open_port=open_port)
        self.ramp_step_s = ramp_step_s
        try:
            self._identity = self.query(IDENTITY)
            self._set(CLEAR_STATUS)                  # stale entries would be blamed on our first setting
            self._set(REMOTE_CV, "REMote")
            self._set(REMOTE_CC, "REMote")
            self.max_current_a = self.query(MAX_CURRENT)
            self._set(VOLTAGE, self.query(MAX_VOLTAGE) if compliance_v is None else compliance_v)
        except BaseException:
            self.link.close()
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
        start = self.query(CURRENT_SETPOINT) if ramp_s > 0 else current_a
        steps = max(1, math.ceil(round(ramp_s / self.ramp_step_s, 9)))
        for k in range(1, steps + 1):
            self.clock.sleep(ramp_s / steps)
            self._set(CURRENT, start + (current_a - start) * k / steps)

    def set_output(self, on: bool) -> None:
        if on:
            self._set(OUTPUT, "ON")
        else:
            self._switch_off()

    def output_is_on(self) -> bool:
        return self.query(OUTPUT_STATE)

    def measure_current_a(self) -> float:
        return self.query(MEASURED_CURRENT)

    def measure_voltage_v(self) -> float:
        return self.query(MEASURED_VOLTAGE)

    def close(self) -> None:
        """Hand the setpoints back to the front panel (one attempt each); the output stays as it is."""
        once = replace(self.retry, attempts=1)
        try:
            for setting in (REMOTE_CV, REMOTE_CC):
                self._set(setting, "LOCal", policy=once)
        finally:
            self.link.close()

    # -- exchanges -----------------------------------------------------------------------------
    def _set(self, setting: Setting, *args: object, policy: RetryPolicy | None = None) -> None:
        """Send a setting and read the error queue; an entry there is a refusal of this setting."""
        line = setting.text(*args)

        def exchange() -> None:
            self.send(setting, *args)
            errors = self._read_errors()
            if errors:
                raise DeviceError(self.name, f"{line!r} refused: {'; '.join(errors)}")
        self.retrying(line, exchange, policy=policy)

    def _switch_off(self) -> None:
        """Safety path: more attempts, and the read-back `OUTPut?` decides, not the error queue."""
        line = OUTPUT.text("OFF")

        def exchange() -> None:
            self.send(OUTPUT, "OFF")
            errors = self._read_errors()
            if errors:
                self.events("device_errors", device=self.name, what=line, errors=errors)
            if self.ask(OUTPUT_STATE):
                raise DeviceError(self.name, f"output still on after {line!r}", transient=True)
        self.retrying(line, exchange, policy=replace(self.retry, attempts=max(self.retry.attempts, OFF_ATTEMPTS)))

    def _read_errors(self) -> list[str]:
        """Drain the error queue (at most its size); the entries other than `0,...`."""
        errors = []
        for _ in range(ERROR_QUEUE_SIZE):
            code, entry = self.ask(ERROR)
            if code == 0:
                break
            errors.append(entry)
        return errors
