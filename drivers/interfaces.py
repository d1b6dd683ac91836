"""Abstract device interfaces of a BRDF goniophotometer.

The application (`rig/`) only ever talks to these interfaces. A real driver
implements one as a *protocol client* (Modbus, SCPI over TCP/serial); a simulator
in `simulators/` is the *peer* of that protocol, or, for the camera, which has no
public wire protocol, an in-process implementation of the interface itself.

Angles are degrees, times seconds, currents amperes, illuminance lux,
luminance cd/m². Every blocking call takes its time from a `Clock`, so that on
the simulated rig moves and exposures cost rig time and no wall time.
"""

from __future__ import annotations

import abc
from dataclasses import dataclass, field
from typing import Any, ClassVar

from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.core.values import Frame, IlluminanceReading, LuminanceImage, SensorInfo, Window


class Device:
    """What every device has: a connection to close. A plain base, not abstract: most devices have
    nothing to release, and those that do override `close`."""

    def close(self) -> None:
        """Release the connection; the default has nothing to release."""


class Axis(Device, abc.ABC):
    """One motorised rotation axis (degrees)."""

    name: str

    @abc.abstractmethod
    def start_move(self, target_deg: float) -> None:
        """Start an absolute move and return at once."""

    @abc.abstractmethod
    def wait(self, timeout_s: float | None = None) -> None:
        """Block until the axis is in position; raise DeviceError on alarm or timeout."""

    @abc.abstractmethod
    def position_deg(self) -> float:
        """Read-back (encoder) position, the value the dataset records."""

    @abc.abstractmethod
    def is_moving(self) -> bool: ...

    @abc.abstractmethod
    def stop(self) -> None:
        """Decelerate to a stop now. Must be safe to call at any time."""

    @abc.abstractmethod
    def home(self) -> None:
        """Run the homing sequence and block until done."""

    @abc.abstractmethod
    def move_time_s(self, start_deg: float, target_deg: float) -> float:
        """Predicted duration of a move (for plans and timeouts)."""

    def identity(self) -> str:
        return self.name


class TwoAxisPositioner:
    """Two axes moved together: the goniometer camera arm or the sample stage.

    Concrete on purpose: what differs between rigs is the axis driver, not the
    way two axes are started together and waited for.
    """

    def __init__(self, name: str, first: Axis, second: Axis):
        self.name = name
        self.axes = (first, second)

    def move_to(self, first_deg: float, second_deg: float, timeout_s: float | None = None) -> None:
        self.start_move(first_deg, second_deg)
        self.wait(timeout_s)

    def start_move(self, first_deg: float, second_deg: float) -> None:
        """Start both axes and return at once, so that the other positioner can start too."""
        for axis, target in zip(self.axes, (first_deg, second_deg)):
            axis.start_move(target)

    def wait(self, timeout_s: float | None = None) -> None:
        """Block until both axes are in position; DeviceError on alarm or timeout."""
        for axis in self.axes:
            axis.wait(timeout_s)

    def positions_deg(self) -> tuple[float, float]:
        return self.axes[0].position_deg(), self.axes[1].position_deg()

    def move_time_s(self, start: tuple[float, float], target: tuple[float, float]) -> float:
        """Both axes run at once, so the slower one sets the time."""
        return max(ax.move_time_s(s, t) for ax, s, t in zip(self.axes, start, target))

    def stop(self) -> None:
        errors = []
        for axis in self.axes:
            try:
                axis.stop()
            except Exception as exc:  # keep stopping the other axis
                errors.append(exc)
        if errors:
            raise errors[0]

    def home(self) -> None:
        for axis in self.axes:
            axis.home()

    def identity(self) -> str:
        return f"{self.name}[{', '.join(ax.identity() for ax in self.axes)}]"

    def close(self) -> None:
        for axis in self.axes:
            axis.close()


@dataclass(frozen=True)
class OutputLoss:
    """Why a lamp supply's output feeds no lamp though rig switched it on, as the supply tells it.

    `restart`: rig may switch the output on again itself (the supply's own watchdog switched it off: nothing
    holds it off any more); otherwise something outside rig holds it off (an open interlock, a remote
    shut-down, a supply fault, an operator) and the run waits until that clears."""

    reason: str
    restart: bool


class LampSupply(Device, abc.ABC):
    """DC supply of the halogen lamp, driven in constant-current mode."""

    ROLE: ClassVar[str] = "lamp"          # its role among installed drivers (rig.drivers.registry)

    @abc.abstractmethod
    def identity(self) -> str: ...

    @abc.abstractmethod
    def set_current(self, current_a: float, ramp_s: float = 0.0) -> None:
        """Ramp the output current to `current_a` over `ramp_s` (no inrush on a cold filament)."""

    @abc.abstractmethod
    def set_output(self, on: bool) -> None: ...

    @abc.abstractmethod
    def output_is_on(self) -> bool: ...

    @abc.abstractmethod
    def measure_current_a(self) -> float: ...

    @abc.abstractmethod
    def measure_voltage_v(self) -> float: ...

    def output_loss(self) -> OutputLoss | None:
        """Asked when the lamp carries too little current: whether the supply itself keeps the output from the
        lamp, and why; None when it does not say so (then the lamp, e.g. a burn-out, is to blame). A supply that
        cannot tell returns None."""
        return None


class IlluminanceMeter(Device, abc.ABC):
    """Optometer reading E⊥ at the sample position (perpendicular incidence)."""

    ROLE: ClassVar[str] = "meter"          # its role among installed drivers (rig.drivers.registry)

    @abc.abstractmethod
    def identity(self) -> str: ...

    @abc.abstractmethod
    def read(self) -> IlluminanceReading:
        """One reading; illuminance = photocurrent × calibration factor from configuration."""


class LuminanceCamera(Device, abc.ABC):
    """Calibrated luminance camera: raw frames plus the calibration to cd/m² (or, a
    `CalibratedLuminanceCamera`, luminance pictures it calibrates itself)."""

    ROLE: ClassVar[str] = "camera"          # its role among installed drivers (rig.drivers.registry)

    sensor: SensorInfo

    @abc.abstractmethod
    def identity(self) -> str: ...

    @abc.abstractmethod
    def capture(self, exposure_s: float, window: Window | None = None) -> Frame:
        """Expose with the shutter open; read only `window` (full sensor if None)."""

    @abc.abstractmethod
    def capture_dark(self, exposure_s: float, window: Window | None = None) -> Frame:
        """Same exposure with the shutter closed (dark current + offset)."""

    def full_window(self) -> Window:
        return Window(0, 0, self.sensor.width_px, self.sensor.height_px)


class CalibratedLuminanceCamera(LuminanceCamera, abc.ABC):
    """A camera that delivers calibrated luminance (cd/m²) rather than raw counts (TechnoTeam LMK).

    It applies its own calibration, dark subtraction and HDR merge, so rig takes no dark frames
    and merges nothing: rig.acquisition.calibrated_capture captures its points. `sensor` still
    gives the size, the exposure range and the calibration's relative uncertainty (recorded in the
    uncertainty budget); its raw-signal fields are not used. Without a raw path `capture` and
    `capture_dark` raise.
    """

    @abc.abstractmethod
    def capture_luminance(self, exposure_s: float, window: Window | None = None) -> LuminanceImage:
        """One calibrated picture at one exposure time; read only `window` (full sensor if None)."""

    @abc.abstractmethod
    def capture_hdr_luminance(self, max_exposure_s: float, min_exposure_s: float, factor: float,
                              window: Window | None = None) -> LuminanceImage:
        """One high-dynamic-range picture: the camera chooses exposures between the two limits,
        successive ones `factor` apart, and merges them."""

    def capture(self, exposure_s: float, window: Window | None = None) -> Frame:
        raise DeviceError(self.identity(), "delivers calibrated luminance only: no raw frames")

    def capture_dark(self, exposure_s: float, window: Window | None = None) -> Frame:
        raise DeviceError(self.identity(), "delivers calibrated luminance only: it takes its own dark frames")


class Attenuator(Device, abc.ABC):
    """A motorised neutral-density filter wheel in front of the camera: it attenuates the light the camera
    sees by the transmission of the filter in the beam. Positions are the wheel's own numbers (1 …
    `positions`); their calibrated transmissions are the rig file's (`attenuator.filters`), not the
    driver's. Moving blocks until the wheel has settled."""

    ROLE: ClassVar[str] = "attenuator"      # its role among installed drivers (rig.drivers.registry)

    positions: int

    @abc.abstractmethod
    def identity(self) -> str: ...

    @abc.abstractmethod
    def move_to(self, position: int) -> None:
        """Put filter `position` in the beam and return once the wheel is there."""

    @abc.abstractmethod
    def position(self) -> int:
        """The position in the beam, as the wheel reports it."""


@dataclass
class RigDevices:
    """The five devices of one goniophotometer and the clock they run on."""

    arm: TwoAxisPositioner        # arm_azimuth, arm_polar
    stage: TwoAxisPositioner      # stage_vertical, stage_normal
    lamp: LampSupply
    meter: IlluminanceMeter
    camera: LuminanceCamera
    clock: Clock
    simulated: bool = False
    attenuator: Attenuator | None = None
    #: What the last `safe_state` found of the lamp, for the console and the manifest: `lamp_off_confirmed` (the
    #: driver's read-back said off) and `lamp_problem` (why not: the lamp may still be on). One dict shared by the
    #: copies of this object (`dataclasses.replace`, as the runner's tended devices are made).
    exit_report: dict[str, Any] = field(default_factory=dict)

    def identities(self) -> dict[str, str]:
        return {"arm": self.arm.identity(), "stage": self.stage.identity(),
                "lamp": self.lamp.identity(), "meter": self.meter.identity(),
                "camera": self.camera.identity(),
                **({"attenuator": self.attenuator.identity()} if self.attenuator else {})}

    def route_events(self, sink) -> None:
        """Send every driver's retry/reconnect events to `sink(kind, **fields)`.

        Drivers that report events carry an `events` attribute; axes report through
        the controller they share.
        """
        axes = (*self.arm.axes, *self.stage.axes)
        optional = [self.attenuator] if self.attenuator is not None else []
        for dev in (self.lamp, self.meter, self.camera, *optional, *(getattr(a, "controller", a) for a in axes)):
            if hasattr(dev, "events"):
                dev.events = sink

    def safe_state(self) -> list[str]:
        """Lamp off and axes stopped, whatever fails on the way; returns the failures."""
        problems = []
        for what, action in (("lamp output off", lambda: self.lamp.set_output(False)),
                             ("stop arm", self.arm.stop), ("stop stage", self.stage.stop)):
            try:
                action()
            except Exception as exc:  # every step is attempted; each failure is reported
                problems.append(f"{what}: {exc}")
        lamp_problem = next((p for p in problems if p.startswith("lamp")), None)
        self.exit_report.update(lamp_off_confirmed=lamp_problem is None, lamp_problem=lamp_problem)
        return problems

    def close(self) -> None:
        closers = [self.arm.close, self.stage.close, self.lamp.close, self.meter.close, self.camera.close,
                   *([self.attenuator.close] if self.attenuator is not None else [])]
        for close in closers:
            try:
                close()
            except Exception:  # closing is best effort once the rig is safe
                pass
