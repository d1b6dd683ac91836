"""Camera calibration files: what `rig calibrate camera` measured, read back for the rig file's camera.

A calibration file is human-readable YAML (docs/camera-calibration.md) naming a sidecar `.npy` with the
per-pixel flat field, relative to the YAML file. Loading validates both, with one message naming the
file and the key; the rig file's `camera.calibration_file` references it, and then its coefficient,
uncertainty and flat field replace the sensor-derived ones (`calibrated_sensor`).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import yaml
from pydantic import AfterValidator, Field, StringConstraints, model_validator

from rig.config.files import ConfigFileError, parse_model, printable, read_yaml
from rig.config.strict import StrictModel
from rig.core.values import SensorInfo, Window
from rig.physics.camera_calibration import CalibratedSensorInfo

FORMAT: Literal["rig-camera-calibration"] = "rig-camera-calibration"
Positive = Annotated[float, Field(gt=0, le=1e12)]
Rel = Annotated[float, Field(ge=0, le=1)]
Text = Annotated[str, StringConstraints(min_length=1, max_length=500), AfterValidator(printable)]
Exposure = Annotated[float, Field(gt=0, le=3600)]
Dn = Annotated[float, Field(ge=-1e6, le=1e6)]


class CameraCalibrationError(ConfigFileError):
    """A camera calibration file that cannot be used."""


class CalibratedCamera(StrictModel):
    identity: Text
    width_px: int = Field(gt=0, le=100_000)
    height_px: int = Field(gt=0, le=100_000)
    bit_depth: int = Field(ge=8, le=16)


class Reference(StrictModel):
    """The uniform source's luminance at the centre and its relative standard uncertainty (k = 1)."""

    luminance_cd_m2: Positive
    u_rel: Rel


class CoefficientEntry(StrictModel):
    """k: luminance = merged rate (DN/s) / flat field × k, with its relative budget (k = 1)."""

    cd_m2_per_dn_s: Positive
    u_rel: Rel
    budget: dict[Annotated[str, StringConstraints(max_length=40)], Rel]
    centre_window: tuple[int, int, int, int]       # x0, y0, width, height where k holds and the flat is 1

    @model_validator(mode="after")
    def _budget_adds_up(self):
        total = float(np.sqrt(sum(v ** 2 for v in self.budget.values())))
        if abs(total - self.u_rel) > 1e-6 + 1e-3 * self.u_rel:
            raise ValueError(f"u_rel {self.u_rel:g} is not the root sum of squares {total:g} of the budget")
        return self


class DarkEntry(StrictModel):
    exposure_s: Exposure
    mean_dn: Dn
    dsnu_dn: float = Field(ge=0, le=1e6)
    temporal_std_dn: float = Field(ge=0, le=1e6)
    frames: int = Field(ge=2)


class LinearityEntry(StrictModel):
    """Signal above dark at the centre per exposure; deviation from the EMVA fit (None: outside 5–95 %)."""

    exposures_s: list[Exposure] = Field(min_length=3)
    signal_dn: list[Dn]
    deviation_percent: list[float | None]
    le_percent: float = Field(ge=0, le=100)
    u_le_percent: float = Field(ge=0, le=100)

    @model_validator(mode="after")
    def _same_length(self):
        if not len(self.exposures_s) == len(self.signal_dn) == len(self.deviation_percent):
            raise ValueError("exposures_s, signal_dn and deviation_percent must have the same length")
        return self


class FlatEntry(StrictModel):
    file: Annotated[str, StringConstraints(min_length=1, max_length=1000), AfterValidator(printable)]
    exposure_s: Exposure
    prnu_rel: Rel
    u_prnu_rel: Rel
    falloff_degree: int = Field(ge=0, le=8)
    falloff_coefficients: list[float]
    falloff_corner_rel: float = Field(gt=0, le=2)
    u_falloff_corner_rel: Rel

    @model_validator(mode="after")
    def _coefficients(self):
        n = (self.falloff_degree + 1) * (self.falloff_degree + 2) // 2
        if len(self.falloff_coefficients) != n:
            raise ValueError(f"a degree-{self.falloff_degree} fall-off has {n} coefficients, "
                             f"got {len(self.falloff_coefficients)}")
        return self


class PhotonTransferEntry(StrictModel):
    gain_dn_per_e: Positive
    u_gain_dn_per_e: float = Field(ge=0, le=1e12)
    read_noise_e: float = Field(ge=0, le=1e6)
    u_read_noise_e: float = Field(ge=0, le=1e6)


class CameraCalibration(StrictModel):
    format: Literal["rig-camera-calibration"] = FORMAT
    version: Literal[1] = 1
    camera: CalibratedCamera
    date: Text
    method: Text
    reference: Reference
    coefficient: CoefficientEntry
    dark: list[DarkEntry] = Field(min_length=1)
    linearity: LinearityEntry
    flat_field: FlatEntry
    photon_transfer: PhotonTransferEntry | None = None

    @model_validator(mode="after")
    def _centre_on_sensor(self):
        x0, y0, w, h = self.coefficient.centre_window
        cam = self.camera
        if not (x0 >= 0 and y0 >= 0 and w > 0 and h > 0 and x0 + w <= cam.width_px and y0 + h <= cam.height_px):
            raise ValueError(f"coefficient.centre_window {list(self.coefficient.centre_window)} is not inside the "
                             f"{cam.width_px}×{cam.height_px} sensor")
        return self

    @property
    def centre(self) -> Window:
        return Window(*self.coefficient.centre_window)


def flat_path(yaml_path: str | Path, calibration: CameraCalibration) -> Path:
    """The sidecar flat field, relative to the calibration file."""
    return Path(yaml_path).parent / calibration.flat_field.file


def load_camera_calibration(path: str | Path) -> tuple[CameraCalibration, np.ndarray]:
    """The validated calibration and its flat field (H, W); CameraCalibrationError naming file and key."""
    data = read_yaml(path, "camera calibration", CameraCalibrationError)
    cal = parse_model(data, CameraCalibration, source=path, what="camera calibration", error=CameraCalibrationError)
    npy = flat_path(path, cal)
    where = f"{path}: key 'flat_field.file': {npy}"
    try:
        flat = np.load(npy, allow_pickle=False)
    except FileNotFoundError:
        raise CameraCalibrationError(f"{where}: file not found") from None
    except (OSError, ValueError) as exc:
        raise CameraCalibrationError(f"{where}: not a numpy .npy array: {exc}") from None
    shape = (cal.camera.height_px, cal.camera.width_px)
    if flat.shape != shape or flat.dtype.kind != "f":
        raise CameraCalibrationError(f"{where}: a {flat.dtype} array of shape {flat.shape}, not the camera's "
                                     f"floating-point {shape[1]}×{shape[0]} (width×height) flat field")
    if not (np.all(np.isfinite(flat)) and np.all(flat > 0)):
        raise CameraCalibrationError(f"{where}: the flat field must be finite and positive everywhere")
    return cal, flat


def save_camera_calibration(path: str | Path, calibration: CameraCalibration, flat: np.ndarray) -> None:
    """Write the YAML and its sidecar; neither may exist yet (a calibration is a record, not a cache)."""
    path = Path(path)
    npy = flat_path(path, calibration)
    for target in (path, npy):
        if target.exists():
            raise CameraCalibrationError(f"{target}: exists already; choose another --out")
    np.save(npy, np.asarray(flat, dtype=np.float32), allow_pickle=False)
    text = yaml.safe_dump(calibration.model_dump(mode="json"), sort_keys=False, allow_unicode=True, width=110)
    path.write_text(f"# Radiometric calibration of a raw camera, written by `rig calibrate camera`.\n{text}",
                    encoding="utf-8")


def calibrated_sensor(sensor: SensorInfo, path: str | Path) -> CalibratedSensorInfo:
    """`sensor` with the calibration file's coefficient, uncertainty and flat field; refused with a clear
    message if the file was made for another sensor size."""
    cal, flat = load_camera_calibration(path)
    if (cal.camera.width_px, cal.camera.height_px) != (sensor.width_px, sensor.height_px):
        raise CameraCalibrationError(
            f"{path}: made for a {cal.camera.width_px}×{cal.camera.height_px} sensor ({cal.camera.identity}), "
            f"but the rig's camera is {sensor.width_px}×{sensor.height_px}: calibrate this camera")
    fields = {k: getattr(sensor, k) for k in SensorInfo.__dataclass_fields__}
    fields.update(calibration_cd_m2_per_dn_s=cal.coefficient.cd_m2_per_dn_s, calibration_u_rel=cal.coefficient.u_rel)
    return CalibratedSensorInfo(**fields, flat_field=flat)
