"""Suspenders: conditions that pause a run until they clear (Bluesky's RunEngine idea).

A suspender is a small object: a `check()` that says why the run must stay paused (None
once it may go on), the name its `suspended`/`resumed` events carry, and what must be
measured again when it trips. The engine handles every tripped suspender the same way
(rig.acquisition.engine, `Runner._suspend`): discard what the suspender says, pause and
poll its check, re-warm the lamp if it says so, and measure the discarded points again
(with the point in flight, if one was).

Installed from the campaign's `suspenders` section:
- the lamp (current or voltage out of tolerance), polled before every point and checked at most every
  `LampOutOfTolerance.CHECK_EVERY_S` of rig time, and always before rows become final (below); with
  `illuminance.correction: latest` a row is final at once, so the lamp is checked before every point;
- an E⊥ jump beyond the drift limit between two readings, checked at every reading;
and, whenever a device stops answering, a suspender that probes it until it answers again.

The lamp on a schedule, and why no spoiled row survives: a lamp check costs two queries to the supply, the largest
share of the pipeline's round trips beyond the bare acquisition loop when made before every point. Polled on a
schedule, a failure is seen up to CHECK_EVERY_S late, so a check vouches only for the points measured before it,
and a trip discards every point since the last passing check (`Retake.SINCE_CHECK`: one point when the lamp is
checked before every point, as before). Those points can still be discarded because every row becomes final only
after a passing check: the engine checks the polled suspenders for real before each E⊥ reading (whose rows it
closes, also the closing reading of a graceful stop), and any other discard, a pause for another suspender or the
exit path, discards with its own points those the lamp has not vouched for yet (`Installed.to_discard`), so that
`--resume` measures them again. Burn-out and an open circuit (no current), the supply's own trip and drift are
lasting: the next check sees them. A flicker between two checks is missed, as it was between a check and the
point after it; the E⊥ reading at the end of the series catches any change of light beyond the drift limit.
"""

from __future__ import annotations

import abc
import enum
import math
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from rig.config.campaign import Campaign, Lamp
from rig.config.campaign import Suspenders as SuspendersConfig
from rig.config.rigfile import RigConfig
from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.drivers.interfaces import IlluminanceMeter, LampSupply, RigDevices
from rig.physics.illuminance import IlluminanceEstimate

#: The `reason` of points discarded, at a pause for another suspender or at the exit, because no lamp check came
#: after them (module docstring).
UNVOUCHED = "lamp not checked since"


class Retake(enum.Enum):
    """Which points waiting for their closing E⊥ reading a tripped suspender discards."""

    NOTHING = "nothing"                  # a device outage: the exchange it interrupted is repeated
    LAST_POINT = "last point"            # the last point may have been spoiled
    SINCE_CHECK = "since check"          # the lamp: every point since its last passing check
    SINCE_READING = "since reading"      # an E⊥ jump: every point since the last reading


class Suspender(abc.ABC):
    """One condition that pauses the run; `check()` is polled every check_interval_s of rig time."""

    #: The `device` of the suspended/resumed events.
    name: str
    retake: Retake = Retake.NOTHING
    #: The `reason` of the points_discarded event.
    discard_reason: str = ""
    #: Warm the lamp up again before going on (it was off or out of tolerance).
    rewarm: bool = False

    def __init__(self) -> None:
        self.discards: Counter[str] = Counter()     # point id: times this suspender discarded it
        #: Points polled for since this suspender's last passing check (Retake.SINCE_CHECK): no check came after them.
        self.unvouched = 0

    @abc.abstractmethod
    def check(self) -> str | None:
        """Why the run must stay paused, or None when it may go on."""

    def poll(self) -> str | None:
        """`check()` before a point (a suspender may check on a schedule instead)."""
        return self.check()

    def at_risk(self, waiting: int) -> int:
        """How many of the last `waiting` points (those waiting for E⊥) this suspender's condition may have spoiled,
        had it tripped now."""
        return {Retake.NOTHING: 0, Retake.LAST_POINT: min(1, waiting), Retake.SINCE_CHECK: min(self.unvouched, waiting),
                Retake.SINCE_READING: waiting}[self.retake]

    def forget(self, n: int) -> None:
        """The last `n` points waiting for E⊥ were discarded: fewer are left that no check vouched for."""
        self.unvouched = max(self.unvouched - n, 0)

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
    retake = Retake.SINCE_CHECK
    discard_reason = "lamp"
    rewarm = True
    #: Lamp current below this fraction of the setpoint: the pause names a burn-out or an open circuit.
    BURNT_OUT_FRACTION = 0.5
    #: Rig time between two checks of the points' polls while points wait for E⊥: a simulated point takes about a
    #: second of moves and exposures, so about four share a check, and a lamp failure costs at most this much
    #: re-measuring.
    CHECK_EVERY_S = 5.0

    def __init__(self, lamp: LampSupply, current_a: float, tolerances: SuspendersConfig,
                 reference_v: Callable[[], float | None], clock: Clock, check_every_s: float = CHECK_EVERY_S):
        """`tolerances`: the campaign's lamp current and voltage tolerances; `reference_v`: the lamp
        voltage after the last warm-up (None before the first); `clock`: the rig's, for the schedule;
        `check_every_s`: 0 checks before every point (rows appended at once cannot be taken back)."""
        super().__init__()
        self.lamp, self.current_a, self.tolerances, self.reference_v = lamp, current_a, tolerances, reference_v
        self.clock, self.check_every_s = clock, check_every_s
        self.passed_at_s = -math.inf     # clock time of the last passing check
        #: The last check found the output switched off by the supply with nothing holding it off (`output_loss`).
        self.restart = False

    def poll(self) -> str | None:
        """Check when CHECK_EVERY_S has passed since the last passing check; either way the point about to be
        measured is not vouched for until the next check passes (a poll whose point is not kept counts too: at
        worst a point is measured once more)."""
        reason = self.check() if self.clock.now() - self.passed_at_s >= self.check_every_s else None
        self.unvouched += reason is None
        return reason

    def check(self) -> str | None:
        if self.restart:
            # tripped on an output the supply switched off by itself, which nothing holds off: clear, so that the
            # engine's re-warm (rewarm) switches the lamp on again, ramped as at the start
            self.restart = False
            return None
        reason = self._out_of_tolerance()
        if reason is None:
            self.passed_at_s, self.unvouched = self.clock.now(), 0
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
    retake = Retake.SINCE_READING
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

    def to_discard(self, tripped: Suspender | None, waiting: int) -> int:
        """How many of the last `waiting` points to discard when `tripped` trips (None: rows become final without a
        check, at the exit): its own, and any a polled suspender has not vouched for yet (module docstring); the
        polled suspenders count them as gone."""
        n = max((s.at_risk(waiting) for s in (*self.polled, *([tripped] if tripped else []))), default=0)
        for suspender in self.polled:
            suspender.forget(n)
        return n


def install(campaign: Campaign, rig: RigConfig, devices: RigDevices, *, lamp_reference_v: Callable[[], float | None],
            wait: Callable[[float], None]) -> Installed:
    """The suspenders of `campaign.suspenders` for a run on `devices`."""
    sus = campaign.suspenders
    # on a schedule only while points wait for their closing E⊥ reading (module docstring)
    every_s = LampOutOfTolerance.CHECK_EVERY_S if campaign.illuminance.correction == "interpolate" else 0.0
    lamp = LampOutOfTolerance(devices.lamp, rig.lamp.current_a, sus, lamp_reference_v, devices.clock, every_s)
    jump = IlluminanceJump(devices.meter, sus.illuminance_drift_limit_rel, campaign.lamp, rig.meter.repeatability_rel,
                           wait)
    return Installed((lamp,), jump)
