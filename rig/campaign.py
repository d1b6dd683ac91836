"""Campaign files: pydantic models and a loader whose errors name key, value and what is allowed.

The keys `name`, `sample`, `incidence`, `viewing` and `output` follow the contract
in shared/spec/campaign.md; `capture`, `illuminance`, `lamp` and `limits` are
this project's and are documented in the README and in the shipped campaigns.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import Annotated, Any, Literal, Union

from pydantic import (
    BaseModel,
    ConfigDict,
    Discriminator,
    Field,
    Tag,
    field_validator,
    model_validator,
)

from rig.brdf_models import MODELS
from rig.configfile import ConfigFileError, parse_model, read_yaml


class CampaignError(ConfigFileError):
    """A campaign file that cannot be run; the message says where and why."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


Theta = Annotated[float, Field(ge=0.0, le=90.0)]
Phi = Annotated[float, Field(ge=0.0, le=360.0)]


class SimulatedBrdf(_Strict):
    model: str
    params: dict[str, float]

    @field_validator("model")
    @classmethod
    def _known_model(cls, v: str) -> str:
        if v not in MODELS:
            raise ValueError(f"unknown model {v!r}; allowed: {', '.join(sorted(MODELS))}")
        return v

    @model_validator(mode="after")
    def _params_match_model(self):
        model = MODELS[self.model]
        missing = [p for p in model.param_names if p not in self.params]
        extra = [p for p in self.params if p not in model.param_names]
        if missing or extra:
            raise ValueError(f"{self.model} takes parameters {', '.join(model.param_names)}"
                             + (f"; missing {', '.join(missing)}" if missing else "")
                             + (f"; unknown {', '.join(extra)}" if extra else ""))
        for name, value in self.params.items():
            lo, hi = model.bounds[name]
            if not (math.isfinite(value) and lo <= value <= hi):
                raise ValueError(f"{self.model} parameter {name} = {value} outside [{lo}, {hi}]")
        return self


class Sample(_Strict):
    id: str
    description: str = ""
    simulated_brdf: SimulatedBrdf | None = None


class IncidenceSeries(_Strict):
    phi: Phi
    theta: list[Annotated[float, Field(ge=0.0, lt=90.0)]] = Field(min_length=1)


class CentredPattern(_Strict):
    centred_on: Literal["incidence", "mirror", "normal"]
    theta: list[Theta] = Field(min_length=1)
    phi: list[Phi] = Field(min_length=1)


class ExplicitViews(_Strict):
    points: list[tuple[Theta, Phi]] = Field(min_length=1)


def _view_kind(v: Any) -> str:
    """An entry with `points` is a list of explicit directions; anything else is a pattern."""
    if isinstance(v, dict):
        return "explicit" if "points" in v else "pattern"
    return "explicit" if isinstance(v, ExplicitViews) else "pattern"


ViewSpec = Annotated[Union[Annotated[CentredPattern, Tag("pattern")], Annotated[ExplicitViews, Tag("explicit")]],
                     Discriminator(_view_kind)]


class Output(_Strict):
    dir: str = "runs/campaign"


class Capture(_Strict):
    """HDR capture of one point (see rig.capture.CaptureSettings)."""

    roi_px: int = Field(70, ge=4, le=1000)
    mode: Literal["adaptive", "fixed_bracket"] = "adaptive"
    target_snr: float = Field(200.0, gt=0)
    max_frames: int = Field(16, ge=1, le=256)
    bracket_count: int = Field(5, ge=1, le=12)
    bracket_step_stops: float = Field(1.0, gt=0, le=4)
    dark_max_age_s: float | None = Field(1800.0, gt=0)
    probe_exposure_s: float = Field(0.002, gt=0)
    target_fraction: float = Field(0.7, gt=0, le=0.95)
    bracket_stops: float = Field(2.0, gt=0, le=6)
    max_exposures: int = Field(5, ge=1, le=12)
    frames_per_exposure: int = Field(1, ge=1, le=64)
    min_snr: float = Field(10.0, ge=0)
    save_images: bool = False

    @model_validator(mode="after")
    def _frames_consistent(self):
        if self.max_frames < self.frames_per_exposure:
            raise ValueError(f"max_frames ({self.max_frames}) must be at least frames_per_exposure "
                             f"({self.frames_per_exposure})")
        return self


class Illuminance(_Strict):
    """E⊥: `readings` averaged per measurement, re-measured on a schedule, drift-corrected.

    remeasure: `per_series` (at each series start), `every_n_points` or `every_minutes`
    (with `every`); correction: `interpolate` (E⊥ interpolated in rig time between the
    bracketing readings, flag `drift_corrected`) or `latest` (the last reading).
    """

    readings: int = Field(5, ge=1, le=1000)
    remeasure: Literal["per_series", "every_n_points", "every_minutes"] = "per_series"
    every: float = Field(0.0, ge=0)
    correction: Literal["interpolate", "latest"] = "interpolate"

    @model_validator(mode="after")
    def _every_given(self):
        if self.remeasure != "per_series" and not self.every > 0:
            raise ValueError(f"remeasure: {self.remeasure} needs `every` > 0 "
                             f"({'points' if self.remeasure == 'every_n_points' else 'minutes'})")
        return self


class Lamp(_Strict):
    """Warm-up: wait at least min_s, then until two readings check_s apart differ by < stable_rel."""

    warmup_min_s: float = Field(300.0, ge=0)
    warmup_max_s: float = Field(3600.0, gt=0)
    warmup_check_s: float = Field(60.0, gt=0)
    warmup_stable_rel: float = Field(0.002, gt=0)


class Suspenders(_Strict):
    """Conditions that pause the run until they clear, checked every check_interval_s of rig
    time; after max_wait_s the run stops cleanly. Affected points are measured again."""

    lamp_current_tolerance_rel: float = Field(0.02, gt=0)
    lamp_voltage_tolerance_rel: float = Field(0.05, gt=0)
    illuminance_drift_limit_rel: float = Field(0.02, gt=0)
    check_interval_s: float = Field(30.0, gt=0)
    max_wait_s: float = Field(1800.0, ge=0)


class Limits(_Strict):
    max_view_theta_deg: float = Field(85.0, gt=0, le=90)
    grazing_limit_deg: float = Field(88.0, gt=0, le=90)
    skip_roi_unlit: bool = True


class Campaign(_Strict):
    name: str = Field(min_length=1)
    sample: Sample
    incidence: list[IncidenceSeries] = Field(min_length=1)
    viewing: list[ViewSpec] = Field(min_length=1)
    output: Output = Output()
    capture: Capture = Capture()
    illuminance: Illuminance = Illuminance()
    lamp: Lamp = Lamp()
    limits: Limits = Limits()
    suspenders: Suspenders = Suspenders()
    #: `optimised`: series and views ordered for the least rig time (travel-time heuristic);
    #: `table`: the order of the file. Point ids are the same either way.
    ordering: Literal["optimised", "table"] = "optimised"


_UNION_TAGS = {"pattern": CentredPattern, "explicit": ExplicitViews}


def campaign_sha256(path: str | Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def parse_campaign(data: Any, source: str | Path = "<campaign>") -> Campaign:
    return parse_model(data, Campaign, source=source, what="campaign", error=CampaignError, tags=_UNION_TAGS)


def load_campaign(path: str | Path) -> Campaign:
    """Read and validate a campaign file; raise CampaignError with one clear message."""
    return parse_campaign(read_yaml(path, "campaign", CampaignError), path)
