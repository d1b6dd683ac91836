"""Suspenders: conditions that pause a run until they clear (Bluesky's RunEngine idea).

A suspender is a small object: a `check()` that says why the run must stay paused (None
once it may go on), the name its `suspended`/`resumed` events carry, and what must be
measured again when it trips. The engine handles every tripped suspender the same way
(rig.acquisition.engine, `Runner._suspend`): discard what the suspender says, pause and
poll its check, re-warm the lamp if it says so, and measure the discarded points again
(with the point in flight, if one was).

Installed from the campaign's `suspenders` section:
- the lamp (current or voltage out of tolerance), checked before every point;
- an E⊥ jump beyond the drift limit between two readings, checked at every reading;
and, whenever a device stops answering, a suspender that probes it until it answers again.
"""

from __future__ import annotations

import abc
import enum
from collections import Counter
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from rig.config.campaign import Campaign, Lamp
from rig.config.campaign import Suspenders as SuspendersConfig
from rig.config.rigfile import RigConfig
from rig.core.errors import DeviceError
from rig.drivers.interfaces import IlluminanceMeter, LampSupply, RigDevices
from rig.physics.illuminance import IlluminanceEstimate


class Retake(enum.Enum):
    """Which points waiting for their closing E⊥ reading a tripped suspender discards."""

    NOTHING = "nothing"                  # a device outage: the exchange it interrupted is repeated
    LAST_POINT = "last point"            # the lamp: the last point may have been lit by a failing lamp
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

    @abc.abstractmethod
    def check(self) -> str | None:
        """Why the run must stay paused, or None when it may go on."""

    def discarded(self, point_ids: Sequence[str]) -> None:
        """Count the points this suspender discarded; one that limits its re-takes raises here."""
        self.discards.update(point_ids)


class LampOutOfTolerance(Suspender):
    """Lamp current or voltage outside the campaign's tolerance (a burn-out shows as no current)."""

    name = "lamp"
    retake = Retake.LAST_POINT
    discard_reason = "lamp"
    rewarm = True
    #: Lamp current below this fraction of the setpoint: the pause names a burn-out or an open circuit.
    BURNT_OUT_FRACTION = 0.5

    def __init__(self, lamp: LampSupply, current_a: float, tolerances: SuspendersConfig,
                 reference_v: Callable[[], float | None]):
        """`tolerances`: the campaign's lamp current and voltage tolerances; `reference_v`: the lamp
        voltage after the last warm-up (None before the first)."""
        super().__init__()
        self.lamp, self.current_a, self.tolerances, self.reference_v = lamp, current_a, tolerances, reference_v

    def check(self) -> str | None:
        current = self.lamp.measure_current_a()
        wanted = self.current_a
        if abs(current - wanted) > self.tolerances.lamp_current_tolerance_rel * wanted:
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
        """Two meter readings a check interval apart differ by more than the warm-up criterion."""
        first = self.meter.read().illuminance_lx
        self.wait(self.steady.warmup_check_s)
        second = self.meter.read().illuminance_lx
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

    polled: tuple[Suspender, ...]       # checked before every point
    illuminance: IlluminanceJump        # checked at every E⊥ reading


def install(campaign: Campaign, rig: RigConfig, devices: RigDevices, *, lamp_reference_v: Callable[[], float | None],
            wait: Callable[[float], None]) -> Installed:
    """The suspenders of `campaign.suspenders` for a run on `devices`."""
    sus = campaign.suspenders
    lamp = LampOutOfTolerance(devices.lamp, rig.lamp.current_a, sus, lamp_reference_v)
    jump = IlluminanceJump(devices.meter, sus.illuminance_drift_limit_rel, campaign.lamp, rig.meter.repeatability_rel,
                           wait)
    return Installed((lamp,), jump)
