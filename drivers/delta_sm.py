"""Delta Elektronika SM15K (built-in Ethernet) or SM-series supply with a PSC-ETH module, as the lamp supply.

The commands are those of the manual "Ethernet & Sequencer Programming SM15K"
(rev. July 2021): raw TCP on port 8462, one LF-terminated line per command,
replies only to queries. The older PSC-232 / SM-D dialects are not supported.

The lamp runs in constant-current mode: on connect the driver takes over both
setpoints from the front panel (remote hand-over), sets the supply's own
current and voltage limits from the rig file (so no setpoint, ours or the
front panel's, can exceed them) and the voltage setpoint to the lamp's voltage
limit (its rating plus a margin), never to the supply's maximum: an open
filament or a loose socket then sees at most that voltage, on an SM500 too.
The current setpoint rules below it. Current changes are
ramped in steps on the rig clock, because a cold filament has about a tenth of
its hot resistance (inrush). Every number goes out as a plain decimal with
the read-back's four digits (`SOURce:CURrent 4.1700`), never with an exponent.

A lamp that carries no current is not always burnt out: `output_loss()` asks
the supply why (status register A: interlock open, remote shut-down, AC/DC
fail, over-temperature; `SYSTem:WARning?`; an expired watchdog) and says
whether rig may switch the output on again (only after the watchdog switched
it off) or must wait for the cause to clear.

Last on connect the supply's communication watchdog is armed for the whole
session: if no command reaches it for `watchdog_s` (a killed process, a dead
PC, a cut cable) the supply switches its output off by itself. A keep-alive on
the rig clock feeds it during long waits; `close()` disarms it at a clean end.

Every setting is followed by a read of the error queue: an entry is a refusal
(persistent DeviceError naming the command and the entry). The manual
publishes no list of error codes, so only "0 = no error" is relied on. A
setting and its error read are retried together after a transient fault;
settings are absolute, so sending one twice is harmless.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import replace
from typing import Any, TypeVar

from rig.core import events
from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.drivers import delta_sm_commands as scpi
from rig.drivers.delta_sm_commands import plain
from rig.drivers.interfaces import LampSupply, OutputLoss
from rig.drivers.line_instrument import ErrorQueue, LineInstrument, Query, Setting
from rig.drivers.retry import DEFAULT_RETRY, RetryPolicy
from rig.drivers.transport import PortOpener, open_pyserial

#: Switching off is the safety action: it gets at least this many attempts.
OFF_ATTEMPTS = 6
#: The current ramp before `OUTPut OFF` lasts at most this long, however slow the warm-up ramp is.
OFF_RAMP_MAX_S = 2.0
#: Switched off means a measured current below the larger of these (A, and a fraction of the current limit).
OFF_CURRENT_A = 0.01
OFF_CURRENT_REL = 0.01
#: Feeds per watchdog period: one late or lost feed does not let the watchdog expire.
FEEDS_PER_PERIOD = 4
#: The rig-file key of the lamp's voltage limit, named when it is missing.
VOLTAGE_LIMIT_KEY = "lamp.voltage_limit_v"
T = TypeVar("T")


class DeltaSM(LineInstrument, LampSupply):
    """`url`: `socket://host:8462` (SM15K or PSC-ETH), or a pyserial URL.

    `current_a` is the rig's lamp current, `current_limit_a` the limit set in
    the supply, `watchdog_s` the watchdog time, `ramp_s` the rig file's ramp
    (the switch-off ramp is at most OFF_RAMP_MAX_S of it). `voltage_limit_v`
    (the rig file's `lamp.voltage_limit_v`, required) is the supply's voltage
    limit and voltage setpoint.

    `events(kind, **fields)` hears of retries, reconnects, watchdog trouble and
    errors met while switching off; the runner points it at its log. Events of
    the connection itself, before a sink is attached, are held and handed to
    the first sink attached.
    """

    #: Every setting is followed by a read of the error queue; an entry is a refusal of that setting.
    confirmation = ErrorQueue(scpi.ERROR, scpi.ERROR_QUEUE_SIZE)
    holds_events = True

    def __init__(self, url: str, *, clock: Clock, current_a: float, current_limit_a: float, watchdog_s: float,
                 ramp_s: float, name: str = "lamp", timeout_s: float = 1.0, retry: RetryPolicy = DEFAULT_RETRY,
                 voltage_limit_v: float | None, ramp_step_s: float = 0.1, open_port: PortOpener = open_pyserial):
        if ramp_step_s <= 0:
            raise ValueError(f"ramp_step_s must be positive, got {ramp_step_s}")
        self.watchdog_ms = round(watchdog_s * 1000)
        if not scpi.WATCHDOG_MIN_MS <= self.watchdog_ms <= scpi.WATCHDOG_MAX_MS:
            raise ValueError(f"watchdog_s must be 0.02 … 10 s (the supply's range), got {watchdog_s}")
        if not 0 < current_a <= current_limit_a:
            raise DeviceError(name, f"lamp current {current_a:g} A exceeds the current limit {current_limit_a:g} A")
        if voltage_limit_v is None or not voltage_limit_v > 0:
            raise DeviceError(name, f"no lamp voltage limit: set {VOLTAGE_LIMIT_KEY} in the rig file (the lamp's "
                                    "rated voltage plus a margin); rig never programs the supply's maximum voltage")
        self.voltage_limit_v = voltage_limit_v
        super().__init__(url, name=name, clock=clock, timeout_s=timeout_s, retry=retry, open_port=open_port)
        self._answered_at_s = -math.inf          # rig time of the supply's last reply
        self._on = False                         # rig switched the output on (and not off since)
        self._watchdog_off: str | None = None    # the supply's watchdog switched it off since: when
        self._blocked_reported: int | None = None    # the blocking bits of the last `lamp_output_blocked`
        self.ramp_step_s = ramp_step_s
        self.ramp_s = ramp_s
        self.current_limit_a = current_limit_a
        self._once = replace(retry, attempts=1)
        try:
            self._connect(current_a)
        except BaseException:
            self.link.close()
            raise
        self._feed_period_s = self.watchdog_ms / 1000 / FEEDS_PER_PERIOD
        self._fed_last_time = True
        self._cancel_feed: Callable[[], None] | None = clock.keep_alive(self._feed_period_s, self._feed_watchdog)

    @classmethod
    def from_rig(cls, *, clock: Clock, settings: Any, address: str, timeout_s: float = 1.0) -> DeltaSM:
        """The rig-file contract (rig.drivers.registry): `settings` is the rig file's `lamp` section."""
        return cls(address, clock=clock, timeout_s=timeout_s, current_a=settings.current_a,
                   current_limit_a=settings.current_limit_a, watchdog_s=settings.watchdog_s, ramp_s=settings.ramp_s,
                   voltage_limit_v=settings.voltage_limit_v)

    def _connect(self, current_a: float) -> None:
        identity = self.query(scpi.IDENTITY)
        if scpi.MAKER not in identity.upper():
            raise DeviceError(self.name, f"not a Delta Elektronika supply: '*IDN?' answered {identity!r}")
        self._identity = identity
        # Read before anything restarts it: 0 means it expired, so our previous session died with it armed.
        if self.query(scpi.WATCHDOG_STATE) == 0:
            self.events(events.WATCHDOG_EXPIRED_BEFORE_CONNECT, device=self.name,
                        what="the supply's watchdog had switched the output off (a previous session ended "
                             "without closing)")
        self.max_current_a = self.query(scpi.MAX_CURRENT)
        self.max_voltage_v = self.query(scpi.MAX_VOLTAGE)
        for what, value, maximum, unit in (("current limit", self.current_limit_a, self.max_current_a, "A"),
                                           ("lamp current", current_a, self.max_current_a, "A"),
                                           ("voltage limit", self.voltage_limit_v, self.max_voltage_v, "V")):
            if value > maximum:
                raise DeviceError(self.name, f"{what} {value:g} {unit} exceeds the supply's maximum {maximum:g} {unit}")
        self._configure()

    def _configure(self, policy: RetryPolicy | None = None) -> None:
        """The session's settings, on connect and again when the watchdog is found off while the lamp should be on
        (the supply may have restarted: setpoints at 0, table 5.1): remote hand-over, both limits (read back),
        the voltage setpoint at the lamp's limit, the watchdog armed. All are absolute: applying them twice is
        harmless."""
        self.apply(scpi.CLEAR_STATUS, policy=policy)      # stale entries would be blamed on our first setting
        self.apply(scpi.REMOTE_CV, "REMote", policy=policy)
        self.apply(scpi.REMOTE_CC, "REMote", policy=policy)
        self._set_limit(scpi.CURRENT_LIMIT, scpi.CURRENT_LIMIT_VALUE, self.current_limit_a, self.max_current_a, policy)
        self._set_limit(scpi.VOLTAGE_LIMIT, scpi.VOLTAGE_LIMIT_VALUE, self.voltage_limit_v, self.max_voltage_v, policy)
        self.apply(scpi.VOLTAGE, plain(self.voltage_limit_v), policy=policy)
        self.apply(scpi.WATCHDOG_ARM, self.watchdog_ms, policy=policy)

    def _set_limit(self, setting: Setting, query: Query[float], value: float, maximum: float,
                   policy: RetryPolicy | None) -> None:
        """Set an enabled limit and read it back: the supply may round it to its programming step (~0.02 ‰ of
        its maximum); more than 1 ‰ off fails the connection."""
        self.apply(setting, plain(value), policy=policy)
        read_back = self.retrying(query.text(), lambda: self.ask(query), policy=policy)
        if abs(read_back - value) > 0.5e-4 + 1e-3 * maximum:
            what = setting.template.split()[0].rpartition(":")[2].lower()
            raise DeviceError(self.name, f"{what} limit reads back as {read_back:g} {setting.unit} after setting "
                                         f"{value:g} {setting.unit}")

    # -- LampSupply ----------------------------------------------------------------------------
    def identity(self) -> str:
        return self._identity

    def set_current(self, current_a: float, ramp_s: float = 0.0) -> None:
        """Staircase from the present setpoint, one step per `ramp_step_s`, the last one on target.

        A target above the current limit or the supply's maximum is refused before the first step.
        """
        bound, what = min((self.current_limit_a, "the current limit"), (self.max_current_a, "the supply's maximum"))
        if not 0.0 <= current_a <= bound:
            raise DeviceError(self.name, f"current {current_a:g} A outside 0 … {bound:g} A ({what})")
        start = min(self.query(scpi.CURRENT_SETPOINT), bound) if ramp_s > 0 else current_a
        self._ramp(start, current_a, ramp_s)

    def set_output(self, on: bool) -> None:
        if on:
            self.apply(scpi.OUTPUT, "ON")
            self._watchdog_off = self._blocked_reported = None
        else:
            self._switch_off()
        self._on = on

    def output_is_on(self) -> bool:
        return self.query(scpi.OUTPUT_STATE)

    def measure_current_a(self) -> float:
        return self.query(scpi.MEASURED_CURRENT)

    def measure_voltage_v(self) -> float:
        return self.query(scpi.MEASURED_VOLTAGE)

    def output_loss(self) -> OutputLoss | None:
        """Why the output feeds no lamp though rig switched it on: status register A's blocking bits (with the
        supply's warnings), else an output the supply's watchdog switched off (rig may switch it on again),
        else an output switched off at the supply; None when the output is on and nothing blocks it (a burnt-out
        filament). A new blocking cause is reported once as event `lamp_output_blocked`."""
        if not self._on:
            return None
        status = self.query(scpi.STATUS_A)
        blocked = [text for bit, text in scpi.BLOCKING_BITS.items() if status & bit]
        if blocked:
            warnings = self.drain(scpi.WARNING, scpi.ERROR_QUEUE_SIZE, self.query)
            reason = "; ".join(blocked) + (f" (warnings: {'; '.join(warnings)})" if warnings else "")
            bits = status & sum(scpi.BLOCKING_BITS)
            if bits != self._blocked_reported:
                self._blocked_reported = bits
                self.events(events.LAMP_OUTPUT_BLOCKED, device=self.name, status_a=status, reason=reason)
            return OutputLoss(f"the supply blocks its output: {reason}", restart=False)
        if self.query(scpi.OUTPUT_STATE):
            return None
        self._check_watchdog(self.query(scpi.WATCHDOG_STATE), None)      # an expiry no feed has seen yet
        if self._watchdog_off is not None:
            return OutputLoss(f"the supply's communication watchdog switched the output off ({self._watchdog_off}; "
                              f"no command for {self.watchdog_ms / 1000:g} s)", restart=True)
        return OutputLoss("the output was switched off at the supply, not by rig (front panel, web page or "
                          "another client)", restart=False)

    def close(self) -> None:
        """Clean end: stop feeding, disarm the watchdog, hand the setpoints back to the front panel, close the
        link. Each step is tried once even if an earlier one failed; the first failure is raised at the end.
        The output stays as it is."""
        if self._cancel_feed is not None:
            self._cancel_feed()
            self._cancel_feed = None
        steps: list[tuple[Setting, tuple[object, ...]]] = [
            (scpi.WATCHDOG_STOP, ()), (scpi.REMOTE_CV, ("LOCal",)), (scpi.REMOTE_CC, ("LOCal",))]
        first: DeviceError | None = None
        try:
            for setting, args in steps:
                try:
                    self.apply(setting, *args, policy=self._once)
                except DeviceError as exc:
                    first = first or exc
        finally:
            self.link.close()
        if first is not None:
            raise first

    # -- the watchdog ----------------------------------------------------------------------------
    def ask(self, query: Query[T], *args: object, timeout_s: float | None = None) -> T:
        """`LineInstrument.ask`, noting when the supply last answered: the command reached it, and any valid
        command restarts its watchdog (manual §5.6.10), so the keep-alive may skip a feed after it."""
        value = super().ask(query, *args, timeout_s=timeout_s)
        self._answered_at_s = self.clock.now()
        return value

    def _feed_watchdog(self) -> None:
        """Keep-alive (runs during sleeps): one query restarts the watchdog. If it had expired (0) or is off
        (-1: the supply restarted), say so and re-arm it (`_check_watchdog`). A failed feed is reported
        and swallowed, never retried here: if the link stays dead, the watchdog does its job.

        A feed due less than a feed period after the supply answered a command is skipped (the command
        restarted the watchdog), but never two in a row: the supply is silent for less than two feed periods
        (half the watchdog time), and a watchdog found expired or off is still noticed within that time.
        The lamp suspender's checks (every few seconds of rig time between points) each save a feed this way."""
        if self._fed_last_time and self.clock.now() - self._answered_at_s < self._feed_period_s:
            self._fed_last_time = False
            return
        self._fed_last_time = True
        try:
            self._check_watchdog(self.ask(scpi.WATCHDOG_STATE), self._once)
        except DeviceError as exc:
            self.events(events.WATCHDOG_FEED_FAILED, device=self.name, error=str(exc))

    def _check_watchdog(self, remaining_ms: int, policy: RetryPolicy | None) -> None:
        """The watchdog's state as read (the query restarted it). Expired (0): re-arm it. Off (-1): its time-out
        was read elsewhere (a reply lost in a stall) or the supply restarted, so the session's settings are applied
        again with it. Either way, with the lamp on, the output is off until rig switches it on again:
        `output_loss` tells the lamp suspender, whose pause re-warms the lamp."""
        if remaining_ms > 0:
            return
        expired = remaining_ms == 0
        if self._on:
            self._watchdog_off = ("it expired" if expired else "found off: it expired or the supply restarted") + \
                f", noticed at rig time {self.clock.now():.1f} s"
        self.events(events.WATCHDOG_EXPIRED if expired else events.WATCHDOG_OFF, device=self.name,
                    what="re-arming; the supply's output was switched off" if expired else
                    "re-applying the session's settings and re-arming (the supply may have restarted)")
        if expired:
            self.apply(scpi.WATCHDOG_ARM, self.watchdog_ms, policy=policy)
        else:
            self._configure(policy)

    # -- exchanges -----------------------------------------------------------------------------
    def _ramp(self, start: float, target: float, ramp_s: float, policy: RetryPolicy | None = None,
              tolerate_errors: bool = False) -> None:
        steps = max(1, math.ceil(round(ramp_s / self.ramp_step_s, 9)))
        for k in range(1, steps + 1):
            self.clock.sleep(ramp_s / steps)
            self.apply(scpi.CURRENT, plain(target if k == steps else start + (target - start) * k / steps),
                      policy=policy, tolerate_errors=tolerate_errors)

    def _switch_off(self) -> None:
        """Safety path: ramp down (best effort), then `OUTPut OFF`, whatever happened in the ramp."""
        try:
            self._ramp_down()
        except DeviceError as exc:
            self.events(events.SWITCH_OFF_RAMP_FAILED, device=self.name, error=str(exc))
        finally:
            self._output_off()

    def _ramp_down(self) -> None:
        """To 0 A over min(ramp_s, OFF_RAMP_MAX_S), one attempt per exchange; skipped when the output is off
        already (no filament to spare) or the supply does not answer (no time to lose)."""
        ramp_s = min(self.ramp_s, OFF_RAMP_MAX_S)
        if ramp_s <= 0 or not self.ask(scpi.OUTPUT_STATE):
            return
        start = self.ask(scpi.CURRENT_SETPOINT)
        if start > 0:
            self._ramp(start, 0.0, ramp_s, policy=self._once, tolerate_errors=True)

    def _output_off(self) -> None:
        """More attempts, and the read-backs decide, not the error queue: `OUTPut?` off and no current."""
        line = scpi.OUTPUT.text("OFF")
        threshold_a = max(OFF_CURRENT_A, OFF_CURRENT_REL * self.current_limit_a)

        def exchange() -> None:
            self.put(scpi.OUTPUT, "OFF", tolerate_errors=True)
            if self.ask(scpi.OUTPUT_STATE):
                raise DeviceError(self.name, f"output still on after {line!r}", transient=True)
            current_a = self.ask(scpi.MEASURED_CURRENT)
            if abs(current_a) >= threshold_a:
                raise DeviceError(self.name, f"output still carries {current_a:g} A after {line!r} "
                                             f"(off means below {threshold_a:g} A)", transient=True)
        self.retrying(line, exchange, policy=replace(self.retry, attempts=max(self.retry.attempts, OFF_ATTEMPTS)))
