"""The rig file's `geometry` section (GeometryConfig) and geometry calibration files: what `rig calibrate geometry`
found (docs/geometry-calibration.md), read back for the section's `calibration_file`.

The file is human-readable YAML: the board and the camera's intrinsics it was made with, every fitted parameter
with its standard uncertainty (k = 1) and their covariance, and the fit's report (each view's residual, the views
rejected and why). The rig file references it; loading it there fills `geometry.calibration`
(`GeometryCalibrationSummary`: the axes' zero offsets that moves and reported angles apply, their uncertainty,
which becomes `geometry.angle_u_deg`, and the date the report shows).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Literal

import numpy as np
import yaml
from pydantic import AfterValidator, Field, StringConstraints, model_validator

from rig.config.files import ConfigFileError, parse_model, printable, read_yaml
from rig.config.strict import StrictModel
from rig.physics.geometry import AXIS_NAMES
from rig.physics.goniometer_fit import PARAMETERS

FORMAT: Literal["rig-geometry-calibration"] = "rig-geometry-calibration"
Text = Annotated[str, StringConstraints(min_length=1, max_length=500), AfterValidator(printable)]
Finite = Annotated[float, Field(ge=-1e9, le=1e9, allow_inf_nan=False)]
Uncertainty = Annotated[float, Field(ge=0, le=1e6, allow_inf_nan=False)]
#: Distances on the rig (m).
Metres = Annotated[float, Field(gt=0, le=100)]
#: The parameters that are the axes' zero offsets, in AXIS_NAMES' order.
ZERO_PARAMETERS = tuple(f"{axis}_zero_deg" for axis in AXIS_NAMES)


class GeometryCalibrationError(ConfigFileError):
    """A geometry calibration file that cannot be used."""


class Estimate(StrictModel):
    """A fitted value and its standard uncertainty (k = 1)."""

    value: Finite
    u: Uncertainty


class BoardEntry(StrictModel):
    squares_x: int = Field(ge=3, le=40)
    squares_y: int = Field(ge=3, le=40)
    square_m: float = Field(gt=0, le=1)
    marker_m: float = Field(gt=0, le=1)
    dictionary: Text


class IntrinsicsEntry(StrictModel):
    """The camera's matrix and OpenCV distortion coefficients as `cv2.calibrateCamera` found them."""

    width_px: int = Field(gt=0, le=100_000)
    height_px: int = Field(gt=0, le=100_000)
    matrix: list[list[Finite]]
    distortion: list[Finite]
    rms_px: Uncertainty


class ViewEntry(StrictModel):
    """One view of the fit: its axes (encoder readings), what was seen and its residual RMS (px)."""

    label: Text
    kind: Literal["board", "lamp"]
    motors_deg: tuple[Finite, Finite, Finite, Finite]
    points: int = Field(ge=0)
    rms_px: Uncertainty | None = None
    rejected: Text | None = None


class FitEntry(StrictModel):
    corner_sigma_px: Uncertainty
    lamp_sigma_px: Uncertainty
    views: list[ViewEntry]


class GeometryCalibration(StrictModel):
    format: Literal["rig-geometry-calibration"] = FORMAT
    version: Literal[1] = 1
    rig: Text
    date: Text
    method: Text
    board: BoardEntry
    intrinsics: IntrinsicsEntry
    parameters: dict[str, Estimate]
    #: How far the camera looks past the goniometer's centre along the image's columns (x) and rows (y), from the
    #: principal point (rig.physics.goniometer_fit.pointing_deg).
    pointing_x_deg: Estimate
    pointing_y_deg: Estimate
    #: Covariance of `parameters`, in their order and units.
    covariance: list[list[Finite]]
    fit: FitEntry

    @model_validator(mode="after")
    def _complete(self):
        if list(self.parameters) != list(PARAMETERS):
            raise ValueError(f"parameters must be {', '.join(PARAMETERS)}, in this order")
        n = len(PARAMETERS)
        if len(self.covariance) != n or any(len(row) != n for row in self.covariance):
            raise ValueError(f"covariance must be {n}×{n}")
        return self

    def zero_offsets_deg(self) -> tuple[float, float, float, float]:
        """Each axis's zero offset (physical angle = encoder reading + offset), in AXIS_NAMES' order."""
        a, b, c, d = (self.parameters[name].value for name in ZERO_PARAMETERS)
        return a, b, c, d

    def zero_u_deg(self) -> tuple[float, float, float, float]:
        a, b, c, d = (self.parameters[name].u for name in ZERO_PARAMETERS)
        return a, b, c, d


class GeometryCalibrationSummary(StrictModel):
    """What a rig takes from its geometry calibration file: filled at load (rig.config.rigfile), never typed."""

    file: Text
    date: Text
    zero_offsets_deg: tuple[Finite, Finite, Finite, Finite]
    zero_u_deg: tuple[Uncertainty, Uncertainty, Uncertainty, Uncertainty]


class GeometryConfig(StrictModel):
    """The rig file's `geometry` section: distances, the axes' angle uncertainty, the geometry calibration."""

    lamp_distance_m: Metres = 0.92
    camera_distance_m: Metres = 1.54
    lamp_housing_radius_m: float = Field(0.04, ge=0, le=10)
    spot_diameter_m: Metres = 0.075
    #: Standard uncertainty of every axis position (zero, positioning and read-back together).
    angle_u_deg: float = Field(0.01, ge=0, le=10)
    #: The part of `angle_u_deg` that differs from one position to the next on the same axis (encoder
    #: resolution and interpolation error): what is left once a campaign's `alignment` has measured the
    #: fixed zero errors (rig.physics.budget.lobe_view_u_deg).
    readback_u_deg: float = Field(0.002, ge=0, le=10)
    #: What `rig calibrate geometry` wrote (relative to the rig file, docs/geometry-calibration.md): its axis zero
    #: offsets are applied to every move and read-back, and `angle_u_deg` comes from its uncertainty.
    calibration_file: Annotated[str, StringConstraints(min_length=1, max_length=1000),
                                AfterValidator(printable)] | None = None
    #: Filled from `calibration_file` when the rig file is loaded (load_rig_config); not typed in a rig file.
    calibration: GeometryCalibrationSummary | None = None

    @model_validator(mode="after")
    def _calibration_from_its_file(self):
        if self.calibration is not None and self.calibration_file is None:
            raise ValueError("calibration is written by rig from calibration_file; give that key instead")
        return self

    @model_validator(mode="after")
    def _readback_within_angle_u(self):
        if self.readback_u_deg > self.angle_u_deg:
            raise ValueError(f"readback_u_deg {self.readback_u_deg:g} exceeds angle_u_deg {self.angle_u_deg:g}, "
                             "of which it is a part")
        return self


def calibrated_geometry(calibration_file: str, folder: Path, readback_u_deg: float) -> dict[str, object]:
    """The geometry section's update for its `calibration_file` (relative to the rig file's `folder`): the file's
    path, what it holds (GeometryCalibrationSummary) and `angle_u_deg` from its uncertainty, whatever the rig file
    typed: the largest zero offset's u with the read-back's, which varies from one position to the next
    (rig.physics.budget). GeometryCalibrationError naming the file and key of a file that cannot be used."""
    file = str(folder / calibration_file)
    found = summary(file)
    return {"calibration_file": file, "calibration": found,
            "angle_u_deg": float(np.hypot(max(found.zero_u_deg), readback_u_deg))}


def load_geometry_calibration(path: str | Path) -> GeometryCalibration:
    """The validated calibration; GeometryCalibrationError naming the file and the key."""
    data = read_yaml(path, "geometry calibration", GeometryCalibrationError)
    return parse_model(data, GeometryCalibration, source=path, what="geometry calibration",
                       error=GeometryCalibrationError)


def summary(path: str | Path) -> GeometryCalibrationSummary:
    cal = load_geometry_calibration(path)
    return GeometryCalibrationSummary(file=str(path), date=cal.date, zero_offsets_deg=cal.zero_offsets_deg(),
                                      zero_u_deg=cal.zero_u_deg())


def save_geometry_calibration(path: str | Path, calibration: GeometryCalibration) -> None:
    """Write the YAML; it may not exist yet (a calibration is a record, not a cache)."""
    path = Path(path)
    if path.exists():
        raise GeometryCalibrationError(f"{path}: exists already; choose another --out")
    text = yaml.safe_dump(calibration.model_dump(mode="json"), sort_keys=False, allow_unicode=True, width=110)
    path.write_text(f"# Geometric calibration of a goniometer, written by `rig calibrate geometry`.\n{text}",
                    encoding="utf-8")


def covariance_list(covariance: np.ndarray) -> list[list[float]]:
    return [[float(v) for v in row] for row in np.asarray(covariance, float)]
