"""Suspenders: conditions that pause a run until they clear (Bluesky's RunEngine idea).

A suspender is a small object: a `check()` that says why the run must stay paused (None
once it may go on), the name its `suspended`/`resumed` events carry, and the checkpoint a
trip rewinds to. The engine handles every tripped suspender the same way
(rig.acquisition.engine, `Runner._suspend`): rewind the ledger to that checkpoint, pause and
poll its check, re-warm the lamp if it says so, and measure the discarded points again
(with the point in flight, if one was).

Installed from the campaign's `suspenders` section:
- the lamp (current or voltage out of tolerance), polled before every point and checked at most every
  `LampOutOfTolerance.CHECK_EVERY_S` of rig time, and always before rows become final; with
  `illuminance.correction: latest` a row is final at once, so the lamp is checked before every point;
- an E⊥ jump beyond the drift limit between two readings, checked at every reading;
and, whenever a device stops answering, a suspender that probes it until it answers again.

What a trip takes back is a checkpoint the suspender names (`rewind_to`, a rig.acquisition.ledger.Mark): the lamp
rewinds to its last passing check (which marks the ledger: a check costs two queries to the supply, so it is made on
a schedule and vouches only for the points before it), an E⊥ jump to the last reading, a silent device to neither
(the exchange it interrupted is repeated). The ledger's module docstring says why no unvouched row becomes final.
Burn-out and an open circuit (no current), the supply's own trip and drift are lasting: the next check sees them. A
flicker between two checks is missed, as it was between a check and the point after it; the E⊥ reading at the end
of the series catches any change of light beyond the drift limit.
"""

from __future__ import annotations

import abc
import math
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from rig.acquisition.ledger import Mark
from rig.config.campaign import Campaign, Lamp
from rig.config.campaign import Suspenders as SuspendersConfig
from rig.config.rigfile import RigConfig
from rig.core import events
from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.drivers.interfaces import IlluminanceMeter, LampSupply, RigDevices
from rig.physics.illuminance import IlluminanceEstimate

#: The `reason` of points discarded, at a pause for another suspender or at the exit, because no lamp check came
#: after them (rig.acquisition.ledger).
UNVOUCHED = "lamp not checked since"


class Suspender(abc.ABC):
    """One condition that pauses the run; `check()` is polled every check_interval_s of rig time."""

    #: The `device` of the suspended/resumed events.
    name: str
    #: The checkpoint a trip rewinds to: the waiting points since it are measured again (None: no point of its own).
    rewind_to: Mark | None = None
    #: The `reason` of the points_discarded event.
    discard_reason: str = ""
    #: Warm the lamp up again before going on (it was off or out of tolerance).
    rewarm: bool = False

    def __init__(self) -> None:
        self.discards: Counter[str] = Counter()     # point id: times this suspender discarded it

    @abc.abstractmethod
    def check(self) -> str | None:
        """Why the run must stay paused, or None when it may go on."""

    def poll(self) -> str | None:
        """`check()` before a point (a suspender may check on a schedule instead)."""
        return self.check()

    def discarded(self, point_ids: Sequence[str]) -> None:
        """Count the points this suspender discarded; one that limits its re-takes raises here."""
        self.discards.update(point_ids)


class LampOutOfTolerance(Suspender):
    """Lamp current or voltage outside the campaign's tolerance (a burn-out shows as no current); polled on a
    schedule (module docstring). Too little current is first put to the supply (`LampSupply.output_loss`): an output
    it blocks (an open interlock, a remote shut-down, a fault) pauses the run under that name until it clears; an
    output its watchdog switched off (rig stalled longer than the watchdog) clears the pause at once, and the re-warm
    switches the lamp on again."""

    name = "lamp"
    rewind_to = Mark.LAMP_CHECKED
    discard_reason = "lamp"
    rewarm = True
    #: Lamp current below this fraction of the setpoint: the pause names a burn-out or an open circuit.
    BURNT_OUT_FRACTION = 0.5
    #: Rig time between two checks of the points' polls while points wait for E⊥: a simulated point takes about a
    #: second of moves and exposures, so about four share a check, and a lamp failure costs at most this much
    #: re-measuring.
    CHECK_EVERY_S = 5.0

    def __init__(self, lamp: LampSupply, current_a: float, tolerances: SuspendersConfig,
                 reference_v: Callable[[], float | None], clock: Clock, check_every_s: float = CHECK_EVERY_S,
                 mark: Callable[[Mark], None] = lambda mark: None):
        """`tolerances`: the campaign's lamp current and voltage tolerances; `reference_v`: the lamp
        voltage after the last warm-up (None before the first); `clock`: the rig's, for the schedule;
        `check_every_s`: 0 checks before every point (rows appended at once cannot be taken back);
        `mark`: the run's ledger's, told where each check passed."""
        super().__init__()
        self.lamp, self.current_a, self.tolerances, self.reference_v = lamp, current_a, tolerances, reference_v
        self.clock, self.check_every_s, self.mark = clock, check_every_s, mark
        self.passed_at_s = -math.inf     # clock time of the last passing check
        #: The last check found the output switched off by the supply with nothing holding it off (`output_loss`).
        self.restart = False

    def poll(self) -> str | None:
        """Check when CHECK_EVERY_S has passed since the last passing check; either way the point about to be
        measured is not vouched for until the next check passes (rig.acquisition.ledger)."""
        return self.check() if self.clock.now() - self.passed_at_s >= self.check_every_s else None

    def check(self) -> str | None:
        if self.restart:
            # tripped on an output the supply switched off by itself, which nothing holds off: clear, so that the
            # engine's re-warm (rewarm) switches the lamp on again, ramped as at the start
            self.restart = False
            return None
        reason = self._out_of_tolerance()
        if reason is None:
            self.passed_at_s = self.clock.now()
            self.mark(Mark.LAMP_CHECKED)
        return reason

    def _out_of_tolerance(self) -> str | None:
        current = self.lamp.measure_current_a()
        wanted = self.current_a
        if abs(current - wanted) > self.tolerances.lamp_current_tolerance_rel * wanted:
            if (loss := self.lamp.output_loss()) is not None:      # not the lamp: the supply feeds it nothing
                self.restart = loss.restart
                return f"lamp output off: {loss.reason}" + ("; switching it on again and re-warming" if loss.restart
                                                            else "; the run goes on once that is cleared")
            return (f"lamp current {current:.3f} A at {self.lamp.measure_voltage_v():.2f} V with {wanted:.3f} A "
                    "set" + (": lamp burnt out or circuit open" if current < self.BURNT_OUT_FRACTION * wanted else ""))
        voltage = self.lamp.measure_voltage_v()
        ref_v = self.reference_v()
        if ref_v and abs(voltage - ref_v) > self.tolerances.lamp_voltage_tolerance_rel * ref_v:
            return f"lamp voltage {voltage:.3f} V, {ref_v:.3f} V after warm-up"
        return None


class IlluminanceJump(Suspender):
    """E⊥ changed beyond `suspenders.illuminance_drift_limit_rel` between two readings.

    Not drift to interpolate but an event: the points since the previous reading are
    discarded and the run pauses until two meter readings a warm-up check interval
    apart agree within the warm-up criterion.
    """

    name = "illuminance"
    rewind_to = Mark.READING
    discard_reason = "illuminance jump"
    #: A point discarded for an E⊥ jump is re-taken at most this many times; one more jump
    #: fails the run (a drift limit the lamp and meter cannot meet would re-take for ever).
    max_retakes = 3

    def __init__(self, meter: IlluminanceMeter, limit_rel: float, steady: Lamp, repeatability_rel: float,
                 wait: Callable[[float], None]):
        """`steady`: the campaign's warm-up criterion (readings `warmup_check_s` apart agree within
        `warmup_stable_rel`); `wait(seconds)`: the engine's wait, which honours a stop request."""
        super().__init__()
        self.meter, self.limit_rel, self.steady, self.wait = meter, limit_rel, steady, wait
        self.repeatability_rel = repeatability_rel       # the meter's, for the message that fails the run
        self.last_change_rel = 0.0

    def jump(self, before: IlluminanceEstimate | None, after: IlluminanceEstimate) -> str | None:
        """Why `after` is a jump from `before` (None: no previous reading, or within the limit)."""
        if before is None or not abs(after.value_lx - before.value_lx) > self.limit_rel * before.value_lx:
            return None
        self.last_change_rel = abs(after.value_lx - before.value_lx) / before.value_lx
        return f"E⊥ {after.value_lx:.1f} lx, {before.value_lx:.1f} lx at the previous reading"

    def check(self) -> str | None:
        """Two meter readings a check interval apart differ by more than the warm-up criterion, or the
        second is in the dark (an underload: below the meter's floor)."""
        first = self.meter.read().illuminance_lx
        self.wait(self.steady.warmup_check_s)
        reading = self.meter.read()
        second = reading.illuminance_lx
        if reading.underload:
            return f"no light on the meter: E⊥ below its floor ({second:.2g} lx)"
        change = abs(second - first) / max(abs(second), 1e-300)
        if change >= self.steady.warmup_stable_rel or not second > 0:
            return f"E⊥ still changing: {first:.1f} → {second:.1f} lx"
        return None

    def discarded(self, point_ids: Sequence[str]) -> None:
        """Fail the run once a point has been discarded more than max_retakes times.

        Failing, not measuring on with flagged points: a limit the lamp and meter cannot meet
        would discard every batch again, for hours of lamp life, and the points it keeps would
        not meet the operator's stated limit. The completed points are kept; after raising the
        limit (or fixing the lamp) `--resume` measures the rest.
        """
        super().discarded(point_ids)
        worst = max(point_ids, key=self.discards.__getitem__, default=None)
        if worst is None or self.discards[worst] <= self.max_retakes:
            return
        raise DeviceError(self.name, (
            f"point {worst} discarded {self.discards[worst]} times for an E⊥ jump beyond "
            f"suspenders.illuminance_drift_limit_rel = {self.limit_rel:g} (last change {self.last_change_rel:.2g}, "
            f"meter repeatability {self.repeatability_rel:g}); raise the limit above the lamp's drift between "
            "readings, or check the lamp, then continue with --resume"))


class DeviceSilent(Suspender):
    """A device stopped answering (its driver's retries ran out): probe it until it answers again."""

    def __init__(self, device: str, probe: Callable[[], object]):
        super().__init__()
        self.name = device
        self.probe = probe

    def check(self) -> str | None:
        try:
            self.probe()
            return None
        except DeviceError as exc:
            return str(exc)


def device_silent(devices: RigDevices, device: str) -> DeviceSilent:
    """The suspender for `device` (a DeviceError's device name): a harmless exchange with it."""
    axes = (*devices.stage.axes, *devices.arm.axes)
    probes: dict[str, Callable[[], object]] = {
        "lamp": devices.lamp.measure_current_a, "meter": devices.meter.read, "camera": devices.camera.identity,
        **{ax.name: ax.position_deg for ax in axes}}
    return DeviceSilent(device, probes.get(device, lambda: [ax.position_deg() for ax in axes]))


@dataclass(frozen=True)
class Installed:
    """The campaign's suspenders on one engine."""

    polled: tuple[Suspender, ...]       # polled before every point, checked before rows become final
    illuminance: IlluminanceJump        # checked at every E⊥ reading

    def tripped(self, answering: Callable[[Callable[[], str | None]], str | None], *,
                now: bool = False) -> tuple[Suspender, str] | None:
        """The first polled suspender that trips, and why: polled before a point, or checked `now` (before the
        rows of the waiting points become final); each exchange goes through `answering` (a silent device pauses)."""
        for suspender in self.polled:
            reason = answering(suspender.check if now else suspender.poll)
            if reason is not None:
                return suspender, reason
        return None


def hold(suspender: Suspender, reason: str, limits: SuspendersConfig, event: Callable[..., None],
         rig_time_s: Callable[[], float], wait: Callable[[float], None], report: Callable[[str], None]) -> None:
    """A pause: `suspender.check()` polled every `limits.check_interval_s` until it clears, with its `suspended` and
    `resumed` events (`event`: the dataset writer's) and progress lines; a DeviceError once `limits.max_wait_s`,
    which bounds the rig time of the whole pause (the checks' own time included), has passed."""
    device = suspender.name
    event(events.SUSPENDED, device=device, reason=reason, rig_time_s=rig_time_s())
    report(f"PAUSED ({device}): {reason}")
    start = rig_time_s()
    while (still := suspender.check()) is not None:
        waited = rig_time_s() - start
        if waited >= limits.max_wait_s:
            event(events.SUSPEND_TIMEOUT, device=device, reason=still, waited_s=waited, rig_time_s=rig_time_s())
            raise DeviceError(device, f"paused {waited:.0f} s and still: {still}")
        wait(min(limits.check_interval_s, limits.max_wait_s - waited))
        report(f"PAUSED ({device}) {rig_time_s() - start:.0f} s: {still}")
    waited = rig_time_s() - start
    event(events.RESUMED, device=device, waited_s=waited, rig_time_s=rig_time_s())
    report(f"resumed after {waited:.0f} s ({device})")


def install(campaign: Campaign, rig: RigConfig, devices: RigDevices, *, lamp_reference_v: Callable[[], float | None],
            wait: Callable[[float], None], mark: Callable[[Mark], None]) -> Installed:
    """The suspenders of `campaign.suspenders` for a run on `devices`; `mark`: the run's ledger's (a passing lamp
    check marks it)."""
    sus = campaign.suspenders
    # on a schedule only while points wait for their closing E⊥ reading (module docstring)
    every_s = LampOutOfTolerance.CHECK_EVERY_S if campaign.illuminance.correction == "interpolate" else 0.0
    lamp = LampOutOfTolerance(devices.lamp, rig.lamp.current_a, sus, lamp_reference_v, devices.clock, every_s, mark)
    jump = IlluminanceJump(devices.meter, sus.illuminance_drift_limit_rel, campaign.lamp, rig.meter.repeatability_rel,
                           wait)
    return Installed((lamp,), jump)
