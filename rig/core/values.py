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
    #: The meter's measuring range for this reading (P-9710: 0 = 2 mA full scale … 7 = 200 pA); None if unknown.
    range_index: int | None = None
    #: Set when the meter saw less than its range resolves (an underload, P-9710 `?32`): the photocurrent lay
    #: somewhere in [0, floor_a), and photocurrent_a / illuminance_lx are that interval's midpoint
    #: (rig.physics.illuminance.below_floor). None for an ordinary reading.
    floor_a: float | None = None

    @property
    def underload(self) -> bool:
        return self.floor_a is not None


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

    pixels_dn: np.ndarray          # uint16, shape (height, width) of `window`; the caller's (not a driver's buffer)
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


@dataclass(frozen=True)
class LuminanceImage:
    """Calibrated luminance of a window, from a camera that calibrates its own pictures (TechnoTeam LMK).

    Such a camera subtracts its own dark signal and merges its own exposures, so rig gets neither
    raw counts nor per-pixel variances: only what the camera reports is here.
    """

    pixels_cd_m2: np.ndarray       # float32, shape (height, width) of `window`, row by row
    window: Window
    exposures_s: tuple[float, ...]  # exposure times the camera used, longest first
    algorithm: str                 # how the camera made the picture: `single` or `high_dynamic`
    #: Fraction (0…1) of the picture's pixels the camera reports as overflowed (the whole picture,
    #: not only `window`: the camera captures the full sensor whatever window is read).
    overflow_fraction: float
    #: Brightest pixel of the picture / the sensor's range (0…1), if the camera reports it: what a
    #: single picture is metered on.
    peak_load: float | None = None
    #: Which pixels of `window` overflowed, where the camera can tell; None if it only reports a fraction.
    saturated: np.ndarray | None = None
    meta: dict = field(default_factory=dict)


@dataclass(frozen=True)
class PointCapture:
    """Result of capturing one point (rig.acquisition.capture): the ROI luminance and how it was obtained.

    The uncertainty components are for the budget table; they are not to be
    added to u_luminance_cd_m2, which already holds them. u_block (the spread of
    block means, `rig.physics.roi`) contains the camera noise and the texture:
    u_block² ≈ u_noise² + u_texture², u_luminance² = u_block² + u_lobe² + (u_rel,cal · L)²;
    and u_noise² = u_frames² + u_dark², where only u_frames is independent from
    point to point (u_dark is shared by the points that reuse the same darks).
    A camera delivering calibrated luminance gives no per-pixel variance: there
    u_noise = u_dark = 0 (unknown, not absent) and u_texture = u_block
    (rig.acquisition.calibrated_capture).
    """

    luminance_cd_m2: float
    u_luminance_cd_m2: float           # block-based ROI uncertainty ⊕ calibration
    roi_std_cd_m2: float               # pixel standard deviation inside the ROI
    exposures_s: tuple[float, ...]     # realised exposure times merged
    saturated_fraction: float          # of ROI pixels, in the longest merged exposure
    flags: tuple[str, ...]             # `low_signal`, `roi_saturated`
    image_cd_m2: np.ndarray | None     # whole merged image when full_frame
    roi_window: Window                 # in sensor coordinates
    n_frames: int                      # raw frames taken, darks excluded
    u_noise_cd_m2: float               # camera noise of the ROI mean, from the merge variance
    u_dark_cd_m2: float                # the part of u_noise due to the subtracted dark frames
    u_texture_cd_m2: float             # ROI non-uniformity: √max(u_block² − u_noise², 0), blocks about the lobe
    capture_time_s: float              # rig time taken (clock), else the summed exposure times
    n_darks: int                       # dark frames taken for this point
    #: The neutral-density filter the point was taken through (rig.acquisition.attenuation): the wheel's
    #: position (0: none, no attenuator or the open position not used), its calibrated transmission (the
    #: luminance is already divided by it) and that transmission's relative standard uncertainty (in
    #: u_luminance_cd_m2 too).
    filter_position: int = 0
    transmission: float = 1.0
    u_rel_attenuation: float = 0.0
    #: The BRDF lobe's curvature over the ROI's angular footprint (rig.physics.footprint), where the fit
    #: resolves it (else 0): the relative bias of the ROI mean against the value at the ROI centre, which
    #: the luminance is corrected to; what that correction adds to the texture's u (in u_luminance_cd_m2 too);
    #: the lobe's half-width over the ROI's half-diagonal, i.e. in units of the view footprint; and its
    #: log-slope |∇ ln f| at the ROI centre per footprint (how much an angle error moves the value).
    lobe_bias_rel: float = 0.0
    u_lobe_cd_m2: float = 0.0
    lobe_width_rel: float = 0.0
    lobe_slope_rel: float = 0.0
    #: The ROI's block pattern (rig.physics.roi.RoiStats.pattern): how the point's texture u splits into the static
    #: grain shared with other views and the rest (rig.physics.static_texture); None where there is none.
    roi_pattern: np.ndarray | None = None
    #: Whether that pattern is about the lobe fit's quadratic (else about the block means' plane): which residual
    #: projector its covariances are estimated with (rig.physics.block_correlation).
    roi_pattern_quadratic: bool = False
    #: Where the lobe is corrected, the centre value's weights on the ROI's log block means (rig.physics.
    #: footprint.centre_weights): how its texture, the block correlation pooled, reaches the value. Else None.
    lobe_weights: np.ndarray | None = None
