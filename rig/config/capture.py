"""The capture schema: each capture parameter's type, bound and default, declared once.

`CaptureParameters` holds the parameters a campaign's `capture` section and a run's capture share, with the
defaults docs/campaign.md documents. The campaign's section (`Capture`: the YAML keys, `save_images` among
them) and the settings one point is captured with (`CaptureSettings`: `full_frame` and the read window's
margin) both extend it, so the schema accepts exactly what rig.acquisition.capturer can capture: a campaign
that validates never fails on its capture settings. See rig.acquisition.capture for what each mode does.
"""

from __future__ import annotations

from typing import Annotated, Self

from pydantic import AfterValidator, Field, model_validator

from rig.config.strict import StrictModel
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


class CaptureParameters(StrictModel):
    """The parameters of a point's capture, in the order of the campaign's `capture` section, with its
    defaults. Validated on construction with the bounds above (pydantic's ValidationError, a ValueError);
    a copy with other values is `model_validate({**x.model_dump(), **changes})`."""

    roi_px: RoiPx = 70                       # side of the central square ROI (px)
    mode: Mode = "adaptive"                  # `adaptive` or `fixed_bracket` (see rig.acquisition.capture)
    target_snr: TargetSnr = 200.0            # adaptive: ROI mean / its camera noise to reach by averaging
    max_frames: MaxFrames = 16               # adaptive: frames per exposure at most
    bracket_count: ExposureCount = 5         # fixed_bracket: exposures
    bracket_step_stops: BracketStepStops = 1.0   # fixed_bracket: their spacing
    dark_max_age_s: DarkMaxAgeS = 1800.0     # darks older than this on the rig clock are re-taken; None: never
    probe_exposure_s: ExposureS = 0.002      # first, metering exposure
    target_fraction: TargetFraction = 0.7    # ROI peak above black level / usable range
    bracket_stops: BracketStops = 2.0        # adaptive: spacing of added shorter exposures
    max_exposures: ExposureCount = 5         # adaptive: exposures merged at most
    frames_per_exposure: FramesPerExposure = 1   # frames averaged per exposure, at least
    min_snr: MinSnr = 10.0                   # ROI mean / its uncertainty below this: `low_signal`

    @model_validator(mode="after")
    def _frames_consistent(self) -> Self:
        if self.max_frames < self.frames_per_exposure:
            raise ValueError(f"max_frames ({self.max_frames}) must be at least frames_per_exposure "
                             f"({self.frames_per_exposure})")
        return self


class CaptureSettings(CaptureParameters):
    """How one point is exposed: the campaign's parameters (`Capture.settings()`) and what only a run sets."""

    full_frame: bool = False                 # read, merge and return the whole sensor (images saved)
    window_margin_px: Annotated[int, Field(ge=0, le=10_000)] = 0   # extra pixels read around the ROI


class Capture(CaptureParameters):
    """The campaign's `capture` section (docs/campaign.md): the capture parameters and `save_images`."""

    save_images: bool = False

    def settings(self) -> CaptureSettings:
        """The capture settings of this section (images saved: the whole frame is merged)."""
        return CaptureSettings(**self.model_dump(exclude={"save_images"}), full_frame=self.save_images)
