"""Rig configuration: geometry, axes, camera, lamp and meter of one goniophotometer.

Defaults describe the LNFG set-up of Spieringhs et al. 2023 (RIGO801 goniometer,
LMK 98-4 camera at 1.54 m, QTH lamp at 0.92 m, 7.5 cm spot). The `simulation`
section is read only by the simulated rig: it holds the truths a real rig
would not know (noise realisations, lamp physics, sample texture).

Rig files are validated as strictly as campaign files, before anything is
connected or written: every number finite and within a sane range, each
device's address in its driver's syntax, axis limits, speeds and accelerations
that fit the controllers' int32 step registers. What needs an import or a
hardware rig (the camera plug-in, real addresses) is checked by
rig.devices.check_devices before connecting.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated, Any

from pydantic import AfterValidator, Field, StringConstraints, model_validator

from rig.config.camera_calibration import calibrated_sensor
from rig.config.capture import MAX_EXPOSURE_S
from rig.config.files import ConfigFileError, parse_model, printable, read_yaml
from rig.config.geometry_calibration import GeometryConfig, calibrated_geometry
from rig.config.rigdevices import (
    DRIVE_STEPS_PER_DEGREE,
    POSITIONER_AXES,
    SERVED_CAMERA,
    AttenuatorDevice,
    DevicesConfig,
)
from rig.config.stated_u import unstated_u
from rig.config.strict import StrictModel
from rig.config.zones import CollisionsConfig
from rig.core.values import SensorInfo
from rig.drivers.modbus_drive_map import DriveMapError, is_map_path, load_drive_map
from rig.physics.geometry import AxisLimits
from rig.physics.optics import CameraOptics

#: Axis positions and limits (deg): two turns either way covers any goniometer axis.
AxisDeg = Annotated[float, Field(ge=-720, le=720)]
#: A device timeout or a settling time (s).
Seconds = Annotated[float, Field(gt=0, le=60)]
#: A relative uncertainty or repeatability.
Rel = Annotated[float, Field(ge=0, le=1)]
#: Axis positions, speeds and accelerations travel as int32 step counts (docs/modbus-drives.md).
INT32_MAX = 2 ** 31 - 1


class AxisConfig(StrictModel):
    limits_deg: tuple[AxisDeg, AxisDeg]
    speed_deg_s: float = Field(gt=0, le=360)
    accel_deg_s2: float = Field(gt=0, le=3600)
    settle_s: float = Field(0.2, ge=0, le=60)

    @model_validator(mode="after")
    def _ordered(self):
        lo, hi = self.limits_deg
        if not lo < hi:
            raise ValueError(f"limits_deg must be [low, high] with low < high, got {list(self.limits_deg)}")
        return self


AXIS_NAMES = ("stage_vertical", "stage_normal", "arm_azimuth", "arm_polar")


class AxesConfig(StrictModel):
    stage_vertical: AxisConfig = AxisConfig(limits_deg=(-90, 90), speed_deg_s=10, accel_deg_s2=20)
    stage_normal: AxisConfig = AxisConfig(limits_deg=(-360, 360), speed_deg_s=20, accel_deg_s2=40)
    arm_azimuth: AxisConfig = AxisConfig(limits_deg=(-180, 180), speed_deg_s=15, accel_deg_s2=30)
    arm_polar: AxisConfig = AxisConfig(limits_deg=(-180, 180), speed_deg_s=15, accel_deg_s2=30)

    def limits(self) -> AxisLimits:
        return AxisLimits(*(getattr(self, n).limits_deg for n in AXIS_NAMES))


class CameraConfig(StrictModel):
    """Sensor and lens of the luminance camera (LMK 98-4: ICX285, 1390×1040, 12 bit).

    `calibration_file` names what `rig calibrate camera` wrote (relative to the rig file): its
    coefficient, uncertainty and flat field then replace the ones derived from responsivity and gain."""

    width_px: int = Field(1390, gt=0, le=100_000)
    height_px: int = Field(1040, gt=0, le=100_000)
    pixel_pitch_um: float = Field(6.45, gt=0, le=1000)
    focal_length_mm: float = Field(50.0, gt=0, le=10_000)
    bit_depth: int = Field(12, ge=8, le=16)
    full_well_e: float = Field(18000.0, gt=0, le=1e9)
    read_noise_e: float = Field(8.0, ge=0, le=1e6)
    black_level_dn: float = Field(64.0, ge=0, le=65535)
    #: Photo-electrons per second per cd/m² of scene luminance (lens + QE + pixel area).
    responsivity_e_per_cd_m2_s: float = Field(900.0, gt=0, le=1e12)
    calibration_u_rel: Rel = 0.0
    min_exposure_s: float = Field(1e-4, gt=0, le=MAX_EXPOSURE_S)
    max_exposure_s: float = Field(15.0, gt=0, le=MAX_EXPOSURE_S)
    #: Time to read the full sensor; a window reads proportionally faster.
    readout_s: float = Field(0.1, ge=0, le=60)
    calibration_file: Annotated[str, StringConstraints(min_length=1, max_length=1000),
                                AfterValidator(printable)] | None = None

    @model_validator(mode="after")
    def _consistent(self):
        if not self.black_level_dn < 2 ** self.bit_depth - 1:
            raise ValueError(f"black_level_dn ({self.black_level_dn:g}) must be below the {self.bit_depth}-bit "
                             f"maximum {2 ** self.bit_depth - 1}")
        if not self.min_exposure_s < self.max_exposure_s:
            raise ValueError(f"min_exposure_s ({self.min_exposure_s:g}) must be below max_exposure_s "
                             f"({self.max_exposure_s:g})")
        return self

    @property
    def gain_dn_per_e(self) -> float:
        return (2 ** self.bit_depth - 1 - self.black_level_dn) / self.full_well_e

    def sensor_info(self) -> SensorInfo:
        """What the pipeline needs; with a calibration file, a CalibratedSensorInfo carrying it
        (CameraCalibrationError if it cannot be used)."""
        sensor = SensorInfo(
            width_px=self.width_px, height_px=self.height_px, bit_depth=self.bit_depth,
            gain_dn_per_e=self.gain_dn_per_e, read_noise_e=self.read_noise_e,
            black_level_dn=self.black_level_dn,
            calibration_cd_m2_per_dn_s=1.0 / (self.responsivity_e_per_cd_m2_s * self.gain_dn_per_e),
            calibration_u_rel=self.calibration_u_rel,
            min_exposure_s=self.min_exposure_s, max_exposure_s=self.max_exposure_s)
        return calibrated_sensor(sensor, self.calibration_file) if self.calibration_file else sensor


class LampConfig(StrictModel):
    current_a: float = Field(4.17, gt=0, le=100)      # 50 W / 12 V QTH
    ramp_s: float = Field(5.0, ge=0, le=600)      # the supply is stepped every 0.1 s on the way
    #: The supply's own current limit (SM15K `SYSTem:LIMits:CURrent`), set on connect: no setpoint, ours or
    #: the front panel's, can exceed it. At least `current_a`.
    current_limit_a: float = Field(4.6, gt=0, le=100)
    #: The supply's communication watchdog (SM15K `SYSTem:COMmunicate:WATchdog`, 0.02–10 s), armed while
    #: rig is connected: if no command arrives for this long (a killed process, a dead PC, a cut cable),
    #: the supply switches its output off by itself. A keep-alive feeds it during long waits.
    watchdog_s: float = Field(5.0, ge=0.02, le=10.0)
    #: The lamp's voltage limit: its rated voltage plus a stated margin (a 12 V lamp: e.g. 14 V, about +15 %).
    #: Programmed as the supply's own voltage limit (SM15K `SYSTem:LIMits:VOLtage`) and as its voltage setpoint,
    #: never the supply's maximum: an open filament or a loose socket sees at most this. Required with a real
    #: delta-sm supply (load_rig_config, and the driver refuses to connect without it); the simulated rig states
    #: it for its 12 V lamp (SIMULATED_LAMP_VOLTAGE_LIMIT_V).
    voltage_limit_v: float | None = Field(None, gt=0, le=1500)      # the largest SM15K is an SM1500

    @model_validator(mode="after")
    def _within_limit(self):
        if self.current_a > self.current_limit_a:
            raise ValueError(f"current_a ({self.current_a:g} A) exceeds current_limit_a ({self.current_limit_a:g} A)")
        return self


#: The simulated lamp's voltage limit: its 12 V rating (rig.simulators.lamp) plus about 15 %.
SIMULATED_LAMP_VOLTAGE_LIMIT_V = 14.0


class MeterConfig(StrictModel):
    #: lx per A of photocurrent, from the detector's calibration certificate.
    calibration_lx_per_a: float = Field(1.0e9, gt=0, le=1e15)
    calibration_u_rel: Rel = 0.0
    #: Relative standard deviation of one reading, used when only one reading is taken.
    repeatability_rel: Rel = 0.002
    #: The meter's own integration time (P-9710 `SN`: 0.1 ms steps, 0.1 ms … 5.9999 s).
    integration_s: float = Field(0.2, ge=1e-4, le=5.9999)
    #: Time the autoranger may add to a reading (range changes settle 2–20 ms each, seven ranges): with
    #: the integration time it sets how long the driver waits for a reply.
    autorange_s: float = Field(0.2, ge=0, le=60)
    #: Relative standard uncertainty a reading has on each range 0 (2 mA full scale) … 7 (200 pA), from the
    #: meter's certificate (offset, linearity); added to the repeatability for the range each reading used.
    range_u_rel: tuple[Rel, Rel, Rel, Rel, Rel, Rel, Rel, Rel] = (0.0,) * 8


class SimulationConfig(StrictModel):
    """Truths of the simulated rig."""

    seed: int = Field(1, ge=0, le=2 ** 63 - 1)
    illuminance_normal_lx: float = Field(5000.0, gt=0, le=1e6)   # E⊥ at nominal current, warm lamp
    lamp_exponent: float = Field(3.4, ge=0, le=10)               # light output ∝ I^3.4
    warmup_amplitude: float = Field(-0.05, gt=-1, le=1)          # output at switch-on relative to warm
    warmup_tau_s: float = Field(120.0, gt=0, le=86400)
    drift_per_hour: float = Field(-0.002, ge=-0.1, le=0.1)       # slow ageing drift after warm-up
    meter_noise_rel: Rel = 0.002
    positioning_sigma_deg: float = Field(0.003, ge=0, le=10)     # repeatability of a move
    dark_current_e_s: float = Field(20.0, ge=0, le=1e9)
    dsnu_e_s: float = Field(2.0, ge=0, le=1e9)                   # pixel-to-pixel dark-current spread
    prnu_rel: Rel = 0.005                                        # pixel-to-pixel gain spread
    #: Relative std of the static reflectance grains at their lattice nodes (seen alike from every view).
    texture_contrast: float = Field(0.03, ge=0, lt=1)
    texture_grain_m: float = Field(0.001, gt=0, le=1)
    #: Relative std of the direction-dependent glint factor (glass beads, aggregate) at its lattice nodes:
    #: it makes the ROI mean change from view to view.
    glint_contrast: float = Field(0.10, ge=0, lt=1)
    #: Spatial lattice pitch of the glints.
    glint_grain_m: float = Field(0.0005, gt=0, le=1)
    #: Lattice pitch of the glints in the half vector's projection on the sample (≈ its rotation near the
    #: normal): ROI means of two views correlate ½ at 0.6 pitch apart and not at all beyond 2 pitches.
    glint_angle_deg: float = Field(2.0, gt=0, le=90)
    #: Std of each axis's fixed zero error (zero calibration, sample mounting), drawn once per run: the
    #: encoders read the physical angle minus it, so it is what `geometry.angle_u_deg` must cover.
    axis_zero_sigma_deg: float = Field(0.01, ge=0, le=10)
    #: Std of the camera's mount about each of its axes (pointing x, y and roll about the optical axis) and of
    #: the sample holder's tilt about the sample x and y axes, drawn once per run: truths for `rig calibrate
    #: geometry` (docs/geometry-calibration.md) beside the axes' zero errors.
    camera_mount_sigma_deg: float = Field(0.0, ge=0, le=10)
    holder_tilt_sigma_deg: float = Field(0.0, ge=0, le=10)
    ambient_cd_m2: float = Field(0.0, ge=0, le=1e6)              # stray light on unlit parts
    #: Relative shortfall β of the charge conversion near zero signal, none at full well
    #: (rig.simulators.sensor.convert_nonlinear): a nonlinearity for `rig calibrate camera` to find.
    nonlinearity_rel: float = Field(0.0, ge=0, le=0.5)


class FilterConfig(StrictModel):
    """One position of the filter wheel and its calibrated transmission (certificate: value and relative
    standard uncertainty, at the camera's spectral response)."""

    position: int = Field(ge=1, le=12)
    transmission: float = Field(gt=0, le=1)
    u_rel: Rel = 0.0


class AttenuatorConfig(StrictModel):
    """The filters of `devices.attenuator`: the clearest is used wherever it does not saturate."""

    filters: list[FilterConfig] = Field(min_length=2, max_length=12)

    @model_validator(mode="after")
    def _distinct(self):
        positions = [f.position for f in self.filters]
        if len(set(positions)) != len(positions):
            raise ValueError(f"filters: each position once, got {positions}")
        transmissions = sorted(f.transmission for f in self.filters)
        if any(a == b for a, b in zip(transmissions, transmissions[1:])):
            raise ValueError("filters: two filters with the same transmission; one would never be chosen")
        return self


#: The simulated rig's filter wheel: an open position and ND filters of optical density 1 … 5 (Thorlabs NE-A
#: series), transmissions as a certificate would state them at the camera's V(λ) response.
SIMULATED_FILTERS = AttenuatorConfig(filters=[
    FilterConfig(position=1, transmission=1.0),
    FilterConfig(position=2, transmission=0.1, u_rel=0.01), FilterConfig(position=3, transmission=0.01, u_rel=0.01),
    FilterConfig(position=4, transmission=1e-3, u_rel=0.015), FilterConfig(position=5, transmission=1e-4, u_rel=0.02),
    FilterConfig(position=6, transmission=1e-5, u_rel=0.03)])


class RigConfig(StrictModel):
    name: Annotated[str, StringConstraints(min_length=1, max_length=200), AfterValidator(printable)] = "simulated"
    simulated: bool = True
    #: Rig seconds per wall second of the devices: 1 for hardware; a served simulated rig (`rig sim serve
    #: --speed N`) writes N, and the client's clock runs as fast, so its waits shrink alike.
    time_scale: float = Field(1.0, gt=0, le=1000)
    devices: DevicesConfig = DevicesConfig()
    geometry: GeometryConfig = GeometryConfig()
    axes: AxesConfig = AxesConfig()
    camera: CameraConfig = CameraConfig()
    lamp: LampConfig = LampConfig()
    meter: MeterConfig = MeterConfig()
    collisions: CollisionsConfig = CollisionsConfig()
    simulation: SimulationConfig = SimulationConfig()
    attenuator: AttenuatorConfig | None = None
    #: Calibration u a real rig's file does not state (rig.config.stated_u): used as 0 and said to be excluded.
    #: The simulated rig's defaults are the simulator's truth (exact conversions, filters drawn within u_rel).
    uncertainty_not_stated: tuple[str, ...] = ()

    @model_validator(mode="before")
    @classmethod
    def _record_unstated_u(cls, data: Any) -> Any:
        if not isinstance(data, dict) or data.get("simulated", True) is True:
            return data
        return {**data, "uncertainty_not_stated": unstated_u(data)}

    @model_validator(mode="after")
    def _attenuator_has_filters(self):
        if (self.devices.attenuator is None) != (self.attenuator is None):
            raise ValueError("devices.attenuator and the attenuator section (its filters) go together: give both "
                             "or neither")
        return self

    @model_validator(mode="before")
    @classmethod
    def _simulated_lamp_voltage_limit(cls, data: Any) -> Any:
        """The simulated rig's lamp is the simulated 12 V one: its voltage limit is stated unless the file does."""
        if not isinstance(data, dict) or data.get("simulated", True) is not True:
            return data
        lamp = data.get("lamp", {})
        if isinstance(lamp, LampConfig) and lamp.voltage_limit_v is None:
            lamp = lamp.model_copy(update={"voltage_limit_v": SIMULATED_LAMP_VOLTAGE_LIMIT_V})
        elif isinstance(lamp, dict) and lamp.get("voltage_limit_v") is None:
            lamp = {**lamp, "voltage_limit_v": SIMULATED_LAMP_VOLTAGE_LIMIT_V}
        return {**data, "lamp": lamp}

    @model_validator(mode="after")
    def _reading_within_watchdog(self):
        """A meter reading blocks for its integration and autoranging: the lamp's keep-alive cannot run
        meanwhile, so that must fit well inside the supply's watchdog."""
        reading_s = self.meter.integration_s + self.meter.autorange_s
        if reading_s > self.lamp.watchdog_s / 2:
            raise ValueError(f"meter.integration_s + meter.autorange_s ({reading_s:g} s) must be at most half of "
                             f"lamp.watchdog_s ({self.lamp.watchdog_s:g} s): a reading blocks the lamp's keep-alive")
        return self

    @model_validator(mode="after")
    def _picture_within_watchdog(self):
        """A vendor camera's picture blocks (the LMK's LabSoft calls do, for all of an HDR series): the lamp's
        keep-alive cannot run meanwhile, so the longest exposure must fit well inside the watchdog."""
        vendor = self.devices.camera.driver not in ("simulated", SERVED_CAMERA)
        if vendor and self.camera.max_exposure_s > self.lamp.watchdog_s / 2:
            raise ValueError(f"camera.max_exposure_s ({self.camera.max_exposure_s:g} s) must be at most half of "
                             f"lamp.watchdog_s ({self.lamp.watchdog_s:g} s) with a vendor camera driver: its "
                             "pictures block the lamp's keep-alive")
        return self

    @model_validator(mode="after")
    def _steps_fit_registers(self):
        """Every axis's limits, speed and acceleration, in steps, fit the controller's int32 registers,
        and speed and acceleration are at least one step (a zero would never move)."""
        for positioner, axes in POSITIONER_AXES.items():
            per_axis = getattr(self.devices, positioner).steps_per_degree
            for index, name in enumerate(axes):
                steps = per_axis if isinstance(per_axis, float | int) else per_axis[index]
                axis = getattr(self.axes, name)
                for what, value in (("limits_deg", max(map(abs, axis.limits_deg))), ("speed_deg_s", axis.speed_deg_s),
                                    ("accel_deg_s2", axis.accel_deg_s2)):
                    if value * steps > INT32_MAX:
                        raise ValueError(f"axes.{name}.{what} {value:g} × devices.{positioner}.steps_per_degree "
                                         f"{steps:g} exceeds the controller's int32 registers")
                    if what != "limits_deg" and round(value * steps) < 1:
                        raise ValueError(f"axes.{name}.{what} {value:g} is less than one step "
                                         f"(devices.{positioner}.steps_per_degree {steps:g})")
        return self


def camera_optics(config: RigConfig) -> CameraOptics:
    """The pinhole model of the rig's camera, in metres (the rig file gives µm and mm)."""
    cam = config.camera
    return CameraOptics(width_px=cam.width_px, height_px=cam.height_px, pixel_pitch_m=cam.pixel_pitch_um * 1e-6,
                        focal_length_m=cam.focal_length_mm * 1e-3, distance_m=config.geometry.camera_distance_m)


class RigConfigError(ConfigFileError):
    """A rig file that cannot be used."""


def load_rig_config(path: str | Path) -> RigConfig:
    """Read and validate a rig file; raise RigConfigError with one clear message.

    Files the rig file names (`camera.calibration_file`, a positioner's drive `map` given by path) are
    made relative to the rig file and read once here, so that a bad one is refused before anything is
    connected."""
    config = parse_model(read_yaml(path, "rig", RigConfigError), RigConfig, source=path, what="rig configuration",
                         error=RigConfigError)
    if config.lamp.voltage_limit_v is None and config.devices.lamp.driver == config.devices.lamp.BUILTIN:
        # else the supply's maximum (500 V on an SM500) would be all that limits the lamp's voltage
        raise RigConfigError(f"{path}: key 'lamp.voltage_limit_v' is required with a delta-sm lamp supply: the lamp's "
                             "rated voltage plus a margin (e.g. 14 for a 12 V lamp); rig never programs the supply's "
                             "maximum")
    folder = Path(path).parent
    update: dict[str, object] = {}
    for name in POSITIONER_AXES:
        entry = getattr(config.devices, name)
        if entry.driver == entry.BUILTIN and is_map_path(entry.map):
            try:
                load_drive_map(str(folder / entry.map))
            except DriveMapError as exc:
                raise RigConfigError(f"{path}: key 'devices.{name}.map': {exc}") from None
            update[name] = entry.model_copy(update={"map": str(folder / entry.map)})
    if update:
        config = config.model_copy(update={"devices": config.devices.model_copy(update=update)})
    if (geometry := config.geometry).calibration_file is not None:       # docs/geometry-calibration.md
        try:
            update = calibrated_geometry(geometry.calibration_file, folder, geometry.readback_u_deg)
        except ConfigFileError as exc:
            raise RigConfigError(f"{path}: key 'geometry.calibration_file': {exc}") from None
        config = config.model_copy(update={"geometry": geometry.model_copy(update=update)})
    cal = config.camera.calibration_file
    if cal is None:
        return config
    camera = config.camera.model_copy(update={"calibration_file": str(folder / cal)})
    try:
        camera.sensor_info()
    except ConfigFileError as exc:
        raise RigConfigError(f"{path}: key 'camera.calibration_file': {exc}") from None
    return config.model_copy(update={"camera": camera})


#: The simulated axes' read-back u: an encoder reads the load's position to ±½ of its drive's step
#: (DRIVE_STEPS_PER_DEGREE), a uniform error of one step/√12, 0.0003° as a rig file states it. What a lab states
#: from its encoders' resolution and interpolation error (the default, 0.002°, is a typical real one); stated 7×
#: too wide, it made a glossy sample's lobe-angle term the largest of its point-to-point u (issue 34).
SIMULATED_READBACK_U_DEG = round(1.0 / DRIVE_STEPS_PER_DEGREE / math.sqrt(12.0), 4)


def simulated_rig() -> RigConfig:
    """The built-in simulated rig (`rig run` without `--rig`; campaigns/rigs/simulated.yaml spells it out):
    the defaults, plus a filter wheel (SIMULATED_FILTERS) and the simulated encoders' read-back u."""
    return RigConfig(devices=DevicesConfig(attenuator=AttenuatorDevice()), attenuator=SIMULATED_FILTERS,
                     geometry=GeometryConfig(readback_u_deg=SIMULATED_READBACK_U_DEG))
