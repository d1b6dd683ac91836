"""Rig configuration: geometry, axes, camera, lamp and meter of one goniophotometer.

Defaults describe the LNFG set-up of Spieringhs et al. 2023 (RIGO801 goniometer,
LMK 98-4 camera at 1.54 m, QTH lamp at 0.92 m, 7.5 cm spot). The `simulation`
section is read only by the simulated rig: it holds the truths a real rig
would not know (noise realisations, lamp physics, sample texture).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from drivers.interfaces import SensorInfo
from rig.collisions import CollisionsConfig
from rig.configfile import ConfigFileError, parse_model, read_yaml
from rig.geometry import AxisLimits


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class AxisConfig(_Strict):
    limits_deg: tuple[float, float]
    speed_deg_s: float = Field(gt=0)
    accel_deg_s2: float = Field(gt=0)
    settle_s: float = Field(0.2, ge=0)

    @model_validator(mode="after")
    def _ordered(self):
        lo, hi = self.limits_deg
        if not lo < hi:
            raise ValueError(f"limits_deg must be [low, high] with low < high, got {list(self.limits_deg)}")
        return self


class AxesConfig(_Strict):
    stage_vertical: AxisConfig = AxisConfig(limits_deg=(-90, 90), speed_deg_s=10, accel_deg_s2=20)
    stage_normal: AxisConfig = AxisConfig(limits_deg=(-360, 360), speed_deg_s=20, accel_deg_s2=40)
    arm_azimuth: AxisConfig = AxisConfig(limits_deg=(-180, 180), speed_deg_s=15, accel_deg_s2=30)
    arm_polar: AxisConfig = AxisConfig(limits_deg=(-180, 180), speed_deg_s=15, accel_deg_s2=30)

    def limits(self) -> AxisLimits:
        return AxisLimits(*(getattr(self, n).limits_deg for n in
                            ("stage_vertical", "stage_normal", "arm_azimuth", "arm_polar")))


class GeometryConfig(_Strict):
    lamp_distance_m: float = Field(0.92, gt=0)
    camera_distance_m: float = Field(1.54, gt=0)
    lamp_housing_radius_m: float = Field(0.04, ge=0)
    spot_diameter_m: float = Field(0.075, gt=0)
    #: Standard uncertainty of every axis position (positioning + read-back).
    angle_u_deg: float = Field(0.01, ge=0)


class CameraConfig(_Strict):
    """Sensor and lens of the luminance camera (LMK 98-4: ICX285, 1390×1040, 12 bit)."""

    width_px: int = Field(1390, gt=0)
    height_px: int = Field(1040, gt=0)
    pixel_pitch_um: float = Field(6.45, gt=0)
    focal_length_mm: float = Field(50.0, gt=0)
    bit_depth: int = Field(12, ge=8, le=16)
    full_well_e: float = Field(18000.0, gt=0)
    read_noise_e: float = Field(8.0, ge=0)
    black_level_dn: float = Field(64.0, ge=0)
    #: Photo-electrons per second per cd/m² of scene luminance (lens + QE + pixel area).
    responsivity_e_per_cd_m2_s: float = Field(900.0, gt=0)
    calibration_u_rel: float = Field(0.0, ge=0)
    min_exposure_s: float = Field(1e-4, gt=0)
    max_exposure_s: float = Field(15.0, gt=0)
    #: Time to read the full sensor; a window reads proportionally faster.
    readout_s: float = Field(0.1, ge=0)

    @property
    def gain_dn_per_e(self) -> float:
        return (2 ** self.bit_depth - 1 - self.black_level_dn) / self.full_well_e

    def sensor_info(self) -> SensorInfo:
        return SensorInfo(
            width_px=self.width_px, height_px=self.height_px, bit_depth=self.bit_depth,
            gain_dn_per_e=self.gain_dn_per_e, read_noise_e=self.read_noise_e,
            black_level_dn=self.black_level_dn,
            calibration_cd_m2_per_dn_s=1.0 / (self.responsivity_e_per_cd_m2_s * self.gain_dn_per_e),
            calibration_u_rel=self.calibration_u_rel,
            min_exposure_s=self.min_exposure_s, max_exposure_s=self.max_exposure_s)


class LampConfig(_Strict):
    current_a: float = Field(4.17, gt=0)      # 50 W / 12 V QTH
    ramp_s: float = Field(5.0, ge=0)


class MeterConfig(_Strict):
    #: lx per A of photocurrent, from the detector's calibration certificate.
    calibration_lx_per_a: float = Field(1.0e9, gt=0)
    calibration_u_rel: float = Field(0.0, ge=0)
    #: Relative standard deviation of one reading, used when only one reading is taken.
    repeatability_rel: float = Field(0.002, ge=0)
    integration_s: float = Field(0.2, ge=0)


class SimulationConfig(_Strict):
    """Truths of the simulated rig."""

    seed: int = 1
    illuminance_normal_lx: float = Field(5000.0, gt=0)   # E⊥ at nominal current, warm lamp
    lamp_exponent: float = 3.4                           # light output ∝ I^3.4
    warmup_amplitude: float = -0.05                      # output at switch-on relative to warm
    warmup_tau_s: float = Field(120.0, gt=0)
    drift_per_hour: float = -0.002                       # slow ageing drift after warm-up
    meter_noise_rel: float = Field(0.002, ge=0)
    positioning_sigma_deg: float = Field(0.003, ge=0)    # repeatability of a move
    encoder_resolution_deg: float = Field(0.001, gt=0)
    dark_current_e_s: float = Field(20.0, ge=0)
    dsnu_e_s: float = Field(2.0, ge=0)                   # pixel-to-pixel dark-current spread
    prnu_rel: float = Field(0.005, ge=0)                 # pixel-to-pixel gain spread
    #: Relative std of the static reflectance grains at their lattice nodes (seen alike from every view).
    texture_contrast: float = Field(0.03, ge=0, lt=1)
    texture_grain_m: float = Field(0.001, gt=0)
    #: Relative std of the direction-dependent glint factor (glass beads, aggregate) at its lattice nodes:
    #: it makes the ROI mean change from view to view.
    glint_contrast: float = Field(0.10, ge=0, lt=1)
    #: Spatial lattice pitch of the glints.
    glint_grain_m: float = Field(0.0005, gt=0)
    #: Lattice pitch of the glints in the half vector's projection on the sample (≈ its rotation near the
    #: normal): ROI means of two views correlate ½ at 0.6 pitch apart and not at all beyond 2 pitches.
    glint_angle_deg: float = Field(2.0, gt=0)
    #: Std of each axis's fixed zero error (zero calibration, sample mounting), drawn once per run: the
    #: encoders read the physical angle minus it, so it is what `geometry.angle_u_deg` must cover.
    axis_zero_sigma_deg: float = Field(0.01, ge=0)
    ambient_cd_m2: float = Field(0.0, ge=0)              # stray light on unlit parts


class PositionerDevice(_Strict):
    """A two-axis motion controller (goniometer arm or sample stage) speaking Modbus."""

    driver: Literal["modbus-axis"] = "modbus-axis"
    #: `modbus-tcp://host:port` or `modbus-rtu://<serial path or pyserial URL>?baudrate=N`;
    #: `auto` on the simulated rig (its peers pick free loopback ports).
    address: str = "auto"
    device_id: int = Field(1, ge=0, le=247)
    steps_per_degree: float = Field(1000.0, gt=0)
    timeout_s: float = Field(1.0, gt=0)


class LampDevice(_Strict):
    driver: Literal["delta-sm"] = "delta-sm"
    address: str = "auto"                       # e.g. socket://192.168.1.20:8462 or /dev/ttyUSB1
    timeout_s: float = Field(1.0, gt=0)


class MeterDevice(_Strict):
    driver: Literal["p9710"] = "p9710"
    address: str = "auto"                       # e.g. /dev/ttyUSB0
    timeout_s: float = Field(1.0, gt=0)


class CameraDevice(_Strict):
    """`simulated`, or `python:package.module:Class` for a vendor-SDK driver (see docs/camera-drivers.md)."""

    driver: str = "simulated"
    options: dict[str, Any] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _known_driver(self):
        if self.driver != "simulated" and not re.fullmatch(r"python:[\w.]+:\w+", self.driver):
            raise ValueError(f"camera driver {self.driver!r}: use 'simulated' or 'python:package.module:Class'")
        return self


class DevicesConfig(_Strict):
    arm: PositionerDevice = PositionerDevice()
    stage: PositionerDevice = PositionerDevice()
    lamp: LampDevice = LampDevice()
    meter: MeterDevice = MeterDevice()
    camera: CameraDevice = CameraDevice()


class RigConfig(_Strict):
    name: str = "simulated"
    simulated: bool = True
    devices: DevicesConfig = DevicesConfig()
    geometry: GeometryConfig = GeometryConfig()
    axes: AxesConfig = AxesConfig()
    camera: CameraConfig = CameraConfig()
    lamp: LampConfig = LampConfig()
    meter: MeterConfig = MeterConfig()
    collisions: CollisionsConfig = CollisionsConfig()
    simulation: SimulationConfig = SimulationConfig()


class RigConfigError(ConfigFileError):
    """A rig file that cannot be used."""


def load_rig_config(path: str | Path) -> RigConfig:
    """Read and validate a rig file; raise RigConfigError with one clear message."""
    return parse_model(read_yaml(path, "rig", RigConfigError), RigConfig, source=path, what="rig configuration",
                       error=RigConfigError)
