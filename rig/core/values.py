"""Value types devices hand to the pipeline: sensor windows, frames, illuminance readings.

and how far a run has got. Units: seconds, pixels, DN (digital numbers), lux, amperes."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class IlluminanceReading:
    illuminance_lx: float
    photocurrent_a: float
    calibration_lx_per_a: float


@dataclass(frozen=True)
class Window:
    """Rectangle of sensor pixels: columns x0..x0+width-1, rows y0..y0+height-1."""

    x0: int
    y0: int
    width: int
    height: int

    @classmethod
    def centred(cls, sensor_width: int, sensor_height: int, width: int, height: int) -> Window:
        return cls((sensor_width - width) // 2, (sensor_height - height) // 2, width, height)

    def inner(self, other: Window) -> tuple[slice, slice]:
        """Array slices of `other` (which must lie inside self) in an image of this window."""
        if not (self.x0 <= other.x0 and self.y0 <= other.y0
                and other.x0 + other.width <= self.x0 + self.width
                and other.y0 + other.height <= self.y0 + self.height):
            raise ValueError(f"window {other} is not inside {self}")
        r0, c0 = other.y0 - self.y0, other.x0 - self.x0
        return slice(r0, r0 + other.height), slice(c0, c0 + other.width)


@dataclass(frozen=True)
class SensorInfo:
    """What the pipeline needs to know of the sensor to merge and weight exposures."""

    width_px: int
    height_px: int
    bit_depth: int
    gain_dn_per_e: float           # K in EMVA 1288
    read_noise_e: float            # temporal dark noise σd
    black_level_dn: float          # offset added by the ADC
    calibration_cd_m2_per_dn_s: float  # luminance = (DN - dark) / t × this
    calibration_u_rel: float = 0.0     # relative standard uncertainty of that factor
    min_exposure_s: float = 1e-4
    max_exposure_s: float = 15.0

    @property
    def saturation_dn(self) -> int:
        return 2 ** self.bit_depth - 1


@dataclass(frozen=True)
class Frame:
    """One raw exposure (or a dark frame taken with the shutter closed)."""

    pixels_dn: np.ndarray          # uint16, shape (height, width) of `window`
    exposure_s: float              # exposure time actually realised
    window: Window
    dark: bool = False
    meta: dict = field(default_factory=dict)


@dataclass
class Progress:
    done: int
    total: int
    rig_time_s: float
    message: str = ""
    #: Estimated rig time to measure the points left (s): the plan's estimate, scaled by
    #: measured / estimated rig time of the points done so far (warm-up and pauses excluded).
    eta_rig_s: float | None = None


#: Called by the run engine after every point (progress bars, the simulators' fault injection).
ProgressCallback = Callable[[Progress], None]
