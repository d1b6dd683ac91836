"""Capture parameters: their types and bounds, and the settings of one point's capture.

The one place they are set. CaptureSettings and the campaign's `capture` section
(rig.config.campaign.Capture) are both declared with these types, so the schema accepts exactly
what rig.acquisition.capture.capture_point can do: a campaign that validates never fails on its
capture settings. See rig.acquisition.capture for what each mode does.
"""

from __future__ import annotations

from typing import Annotated

from pydantic import AfterValidator, ConfigDict, Field
from pydantic.dataclasses import dataclass as pydantic_dataclass

from rig.physics.roi import BLOCK_PX

#: Longest exposure (s) anything may ask for; the sensor's own range clamps further.
MAX_EXPOSURE_S = 3600.0
#: Oldest a dark frame may be allowed to get (s of rig time): a week.
MAX_DARK_AGE_S = 7 * 86400.0

MODES = ("adaptive", "fixed_bracket")


def _known_mode(mode: str) -> str:
    if mode not in MODES:
        raise ValueError(f"capture mode must be one of {', '.join(MODES)}")
    return mode


Mode = Annotated[str, AfterValidator(_known_mode)]
#: Side of the ROI: at least two blocks of rig.physics.roi, whose block means give its uncertainty.
RoiPx = Annotated[int, Field(ge=2 * BLOCK_PX, le=1000)]
ExposureS = Annotated[float, Field(gt=0, le=MAX_EXPOSURE_S)]
#: ROI peak above black level / usable range: below saturation with room for noise.
TargetFraction = Annotated[float, Field(gt=0, le=0.95)]
#: Spacing of added shorter exposures: at least 3 rungs of the 1/6-stop ladder, so that they differ.
BracketStops = Annotated[float, Field(ge=0.5, le=6)]
BracketStepStops = Annotated[float, Field(gt=0, le=4)]
ExposureCount = Annotated[int, Field(ge=1, le=12)]
FramesPerExposure = Annotated[int, Field(ge=1, le=64)]
MaxFrames = Annotated[int, Field(ge=1, le=256)]
TargetSnr = Annotated[float, Field(gt=0, le=1e6)]
MinSnr = Annotated[float, Field(ge=0, le=1e6)]
DarkMaxAgeS = Annotated[float | None, Field(gt=0, le=MAX_DARK_AGE_S)]


def check_frame_counts(max_frames: int, frames_per_exposure: int) -> None:
    """The cross-field rule of the capture parameters (ValueError), shared with rig.config.campaign.Capture."""
    if max_frames < frames_per_exposure:
        raise ValueError(f"max_frames ({max_frames}) must be at least frames_per_exposure ({frames_per_exposure})")


@pydantic_dataclass(frozen=True, config=ConfigDict(extra="forbid", allow_inf_nan=False))
class CaptureSettings:
    """How one point is exposed; built from the campaign file (`Capture.settings()`).

    Validated on construction (also by `dataclasses.replace`) with the bounds above: an
    invalid setting raises pydantic's ValidationError, a ValueError.
    """

    mode: Mode = "adaptive"                  # `adaptive` or `fixed_bracket` (see the module docstring)
    roi_px: RoiPx = 70                       # side of the central square ROI (px)
    probe_exposure_s: ExposureS = 0.002      # first, metering exposure
    target_fraction: TargetFraction = 0.7    # ROI peak above black level / usable range
    bracket_stops: BracketStops = 2.0        # adaptive: spacing of added shorter exposures
    max_exposures: ExposureCount = 5         # adaptive: exposures merged at most
    frames_per_exposure: FramesPerExposure = 1   # frames averaged per exposure, at least
    target_snr: TargetSnr = 200.0            # adaptive: ROI mean / its camera noise to reach by averaging
    max_frames: MaxFrames = 16               # adaptive: frames per exposure at most
    bracket_count: ExposureCount = 5         # fixed_bracket: exposures
    bracket_step_stops: BracketStepStops = 1.0   # fixed_bracket: their spacing
    dark_max_age_s: DarkMaxAgeS = None       # darks older than this on the rig clock are re-taken; None: never
    min_snr: MinSnr = 10.0                   # ROI mean / its uncertainty below this: `low_signal`
    full_frame: bool = False                 # read, merge and return the whole sensor
    window_margin_px: Annotated[int, Field(ge=0, le=10_000)] = 0   # extra pixels read around the ROI

    def __post_init__(self):
        check_frame_counts(self.max_frames, self.frames_per_exposure)
