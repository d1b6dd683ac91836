"""Campaign files: pydantic models and a loader whose errors name key, value and what is allowed.

The keys `name`, `sample`, `incidence`, `viewing` and `output` follow the contract
in docs/campaign.md; `capture`, `illuminance`, `lamp` and `limits` are
this project's and are documented in the README and in the shipped campaigns.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import (
    AfterValidator,
    Discriminator,
    Field,
    StringConstraints,
    Tag,
    field_validator,
    model_validator,
)

from rig.config.capture import Capture
from rig.config.files import ConfigFileError, parse_model, printable, read_yaml, short
from rig.config.rigfile import RigConfig
from rig.config.strict import StrictModel
from rig.config.watchdog import watchdog_problems
from rig.physics.brdf_models import MODELS
from rig.physics.illuminance import GRAZING_LIMIT_DEG


class CampaignError(ConfigFileError):
    """A campaign file that cannot be run; the message says where and why."""



#: A name or id: one printable line.
Name = Annotated[str, StringConstraints(min_length=1, max_length=200), AfterValidator(printable)]
Theta = Annotated[float, Field(ge=0.0, le=90.0)]
#: An azimuth in the SCS, φ in [0, 360) (geometry contract).
Phi = Annotated[float, Field(ge=0.0, lt=360.0)]
#: An azimuth around a pattern's centre: 360 is allowed as the contract's example writes it (≡ 0).
PatternPhi = Annotated[float, Field(ge=0.0, le=360.0)]
#: Longest list of angles (or of incidence entries) in a campaign; MAX_POINTS bounds their products.
MAX_ANGLES = 10_000
#: Most (incidence, view) pairs a campaign may plan; the paper campaign has 2,688.
MAX_POINTS = 100_000
DAY_S = 86400.0


class SimulatedBrdf(StrictModel):
    model: str
    params: dict[str, float]

    @field_validator("model")
    @classmethod
    def _known_model(cls, v: str) -> str:
        if v not in MODELS:
            raise ValueError(f"unknown model {short(v)}; allowed: {', '.join(sorted(MODELS))}")
        return v

    @model_validator(mode="after")
    def _params_match_model(self):
        model = MODELS[self.model]
        missing = [p for p in model.param_names if p not in self.params]
        extra = [short(p) for p in self.params if p not in model.param_names]
        if missing or extra:
            raise ValueError(f"{self.model} takes parameters {', '.join(model.param_names)}"
                             + (f"; missing {', '.join(missing)}" if missing else "")
                             + (f"; unknown {', '.join(extra[:5])}" if extra else ""))
        for name, value in self.params.items():
            lo, hi = model.bounds[name]
            if not (math.isfinite(value) and lo <= value <= hi):
                raise ValueError(f"{self.model} parameter {name} = {value} outside [{lo}, {hi}]")
        return self


class Sample(StrictModel):
    id: Name
    description: Annotated[str, StringConstraints(max_length=2000)] = ""
    simulated_brdf: SimulatedBrdf | None = None


class IncidenceSeries(StrictModel):
    phi: Phi
    theta: list[Annotated[float, Field(ge=0.0, lt=90.0)]] = Field(min_length=1, max_length=MAX_ANGLES)


class CentredPattern(StrictModel):
    centred_on: Literal["incidence", "mirror", "normal"]
    theta: list[Theta] = Field(min_length=1, max_length=MAX_ANGLES)
    phi: list[PatternPhi] = Field(min_length=1, max_length=MAX_ANGLES)

    @property
    def n_views(self) -> int:
        return len(self.theta) * len(self.phi)


class ExplicitViews(StrictModel):
    points: list[tuple[Theta, Phi]] = Field(min_length=1, max_length=MAX_POINTS)

    @property
    def n_views(self) -> int:
        return len(self.points)


def _view_kind(v: Any) -> str:
    """An entry with `points` is a list of explicit directions; anything else is a pattern."""
    if isinstance(v, dict):
        return "explicit" if "points" in v else "pattern"
    return "explicit" if isinstance(v, ExplicitViews) else "pattern"


ViewSpec = Annotated[Annotated[CentredPattern, Tag("pattern")] | Annotated[ExplicitViews, Tag("explicit")],
                     Discriminator(_view_kind)]


class Output(StrictModel):
    dir: Annotated[str, StringConstraints(min_length=1, max_length=4096), AfterValidator(printable)] = "runs/campaign"


class Illuminance(StrictModel):
    """E⊥: `readings` averaged per measurement, re-measured on a schedule, drift-corrected.

    remeasure: `per_series` (at each series start), `every_n_points` or `every_minutes`
    (with `every`); correction: `interpolate` (E⊥ interpolated in rig time between the
    bracketing readings, column `illuminance_interpolated`) or `latest` (the last reading).
    """

    readings: int = Field(5, ge=1, le=1000)
    remeasure: Literal["per_series", "every_n_points", "every_minutes"] = "per_series"
    #: Points (every_n_points) or minutes (every_minutes); a campaign has at most MAX_POINTS points.
    every: float = Field(0.0, ge=0, le=MAX_POINTS)
    correction: Literal["interpolate", "latest"] = "interpolate"

    @model_validator(mode="after")
    def _every_given(self):
        if self.remeasure != "per_series" and not self.every > 0:
            raise ValueError(f"remeasure: {self.remeasure} needs `every` > 0 "
                             f"({'points' if self.remeasure == 'every_n_points' else 'minutes'})")
        return self


class Lamp(StrictModel):
    """Warm-up: wait at least min_s, then until two readings check_s apart differ by < stable_rel,
    at most max_s. A QTH lamp is stable within minutes; a day bounds any warm-up, and checks at
    least a second apart (a meter reading integrates for a fraction of one) bound its readings."""

    warmup_min_s: float = Field(300.0, ge=0, le=DAY_S)
    warmup_max_s: float = Field(3600.0, gt=0, le=DAY_S)
    warmup_check_s: float = Field(60.0, ge=1, le=3600)
    warmup_stable_rel: float = Field(0.002, gt=0, lt=1)

    @model_validator(mode="after")
    def _ordered(self):
        if self.warmup_max_s < self.warmup_min_s:
            raise ValueError(f"warmup_max_s ({self.warmup_max_s:g} s) must be at least warmup_min_s "
                             f"({self.warmup_min_s:g} s)")
        return self


class Suspenders(StrictModel):
    """Conditions that pause the run until they clear, checked every check_interval_s of rig
    time (1 s to an hour); after max_wait_s (at most a week) the run stops cleanly. Affected
    points are measured again."""

    lamp_current_tolerance_rel: float = Field(0.02, gt=0, le=1)
    lamp_voltage_tolerance_rel: float = Field(0.05, gt=0, le=1)
    illuminance_drift_limit_rel: float = Field(0.02, gt=0, le=1)
    check_interval_s: float = Field(30.0, ge=1, le=3600)
    max_wait_s: float = Field(1800.0, ge=0, le=7 * DAY_S)


class Limits(StrictModel):
    max_view_theta_deg: float = Field(85.0, gt=0, le=90)
    grazing_limit_deg: float = Field(GRAZING_LIMIT_DEG, gt=0, le=90)
    skip_roi_unlit: bool = True


class SpecularAlignment(StrictModel):
    """Before the first point, align the arm's zeros on the sample's own specular peak (a glossy sample:
    a gloss standard, a car paint): at incidence `theta_i_deg` the arm scans a `steps` × `steps` grid of
    `step_deg` around the nominal mirror direction, a quadratic in the log of the ROI luminance locates
    the peak (rig.physics.peak_fit), and every later arm move is corrected by the peak's offset. This
    removes the arm's zero error relative to the mounted sample's normal, which on a steep lobe is the
    largest error of a point (rig.acquisition.alignment)."""

    theta_i_deg: float = Field(45.0, ge=5.0, le=80.0)
    step_deg: float = Field(0.2, gt=0.0, le=2.0)
    steps: int = Field(5, ge=3, le=9)
    #: The largest offset the alignment may apply; beyond it the run stops (the sample is not mounted
    #: as the rig expects, or the peak found is not the specular one).
    max_offset_deg: float = Field(0.5, gt=0.0, le=5.0)

    @field_validator("steps")
    @classmethod
    def _odd(cls, v: int) -> int:
        if v % 2 == 0:
            raise ValueError("must be odd (the grid is centred on the nominal mirror direction)")
        return v


class Sampling(StrictModel):
    """Which geometries to measure. `table`: every (incidence, view) pair of the campaign's tables.
    `adaptive`: the tables are the candidate domain (each incidence entry's θ range filled at its finest step,
    every view of the viewing patterns at each, one of each view and its mirror image), and the rig measures a
    first pass (`mandatory` pairs, and `first_pass_incidences` incidences spread over the range, up to
    `batch_points` views each: by default the whole pattern), then one batch of up to `batch_points` views at a
    time, at the incidence where the dataset's interpolant is least certain per second
    of rig time (travel and the E⊥ reading included), until the planned rig time after warm-up reaches
    `budget_rig_time_s` or the interpolant's relative u at every candidate is below `target_u_rel`
    (rig.analysis.adaptive; docs/sampling.md)."""

    mode: Literal["table", "adaptive"] = "table"
    budget_rig_time_s: float | None = Field(None, gt=0, le=7 * DAY_S)
    target_u_rel: float | None = Field(None, gt=0, le=1)
    batch_points: int = Field(256, ge=4, le=1000)
    first_pass_incidences: int = Field(4, ge=2, le=50)
    #: (θi, φi, θo, φo) in degrees that are always measured (in the first pass), e.g. a standard geometry.
    mandatory: list[tuple[Annotated[float, Field(ge=0.0, lt=90.0)], Phi, Theta, Phi]] = Field(
        default_factory=list, max_length=MAX_ANGLES)

    @model_validator(mode="after")
    def _stopping_rule(self):
        if self.mode == "adaptive" and self.budget_rig_time_s is None and self.target_u_rel is None:
            raise ValueError("mode adaptive needs budget_rig_time_s or target_u_rel (or both): when to stop")
        return self


class Campaign(StrictModel):
    name: Name
    sample: Sample
    incidence: list[IncidenceSeries] = Field(min_length=1, max_length=MAX_ANGLES)
    viewing: list[ViewSpec] = Field(min_length=1, max_length=MAX_ANGLES)
    output: Output = Output()
    capture: Capture = Capture()
    illuminance: Illuminance = Illuminance()
    lamp: Lamp = Lamp()
    limits: Limits = Limits()
    suspenders: Suspenders = Suspenders()
    #: `optimised`: series and views ordered for the least rig time (travel-time heuristic);
    #: `table`: the order of the file. Point ids are the same either way.
    ordering: Literal["optimised", "table"] = "optimised"
    #: Align the arm on the sample's specular peak before measuring (glossy samples only).
    alignment: SpecularAlignment | None = None
    #: Measure the whole table, or adaptively where the BRDF needs it.
    sampling: Sampling = Sampling()

    @model_validator(mode="after")
    def _bounded_size(self):
        incidences = sum(len(s.theta) for s in self.incidence)
        views = sum(v.n_views for v in self.viewing)
        if incidences * views > MAX_POINTS:
            raise ValueError(f"{incidences} incidences × {views} views = {incidences * views} points; "
                             f"at most {MAX_POINTS} per campaign (split it)")
        return self


#: How many standard deviations of two E⊥ means' relative difference the drift limit must exceed.
DRIFT_LIMIT_SIGMAS = 5.0


def check_campaign_for_rig(campaign: Campaign, rig: RigConfig, source: str | Path = "<campaign>") -> None:
    """What a valid campaign needs from the rig it runs on; CampaignError if the rig cannot run it.

    - The ROI must fit the camera's sensor (else every capture fails).
    - `suspenders.illuminance_drift_limit_rel` must stand clear of the meter's noise, or
      the E⊥ "jump" it detects is noise and discard/re-take cycles never end. Two E⊥
      means of `readings` readings each, with the meter's repeatability r (relative std
      of one reading), differ by a relative amount of std r·√(2/readings) with the lamp
      perfectly steady. A limit of 5 such standard deviations is exceeded by noise
      alone with a probability of about 6e-7 per reading (normal tails), i.e. less than
      once in a thousand campaigns of a few hundred readings; below it, a false jump
      per campaign becomes likely (3σ: 0.3 % per reading).
    - No device exchange the campaign asks for blocks longer than the lamp supply's watchdog allows
      (rig.config.watchdog): the lamp would go out in the middle of the run.
    """
    problems = []
    sensor_px = min(rig.camera.width_px, rig.camera.height_px)
    if campaign.capture.roi_px > sensor_px:
        problems.append(f"key 'capture.roi_px': value {campaign.capture.roi_px} is not allowed: larger than the "
                        f"rig's {rig.camera.width_px}×{rig.camera.height_px} px sensor")
    noise_rel = rig.meter.repeatability_rel * math.sqrt(2.0 / campaign.illuminance.readings)
    needed = DRIFT_LIMIT_SIGMAS * noise_rel
    limit = campaign.suspenders.illuminance_drift_limit_rel
    if not limit > needed:
        problems.append(f"key 'suspenders.illuminance_drift_limit_rel': value {limit:g} is not allowed: must exceed "
                        f"{needed:.3g}, {DRIFT_LIMIT_SIGMAS:g}× the meter's noise on the difference of two E⊥ "
                        f"readings (repeatability {rig.meter.repeatability_rel:g} of rig {rig.name}, "
                        f"{campaign.illuminance.readings} readings each); raise it or illuminance.readings")
    problems += watchdog_problems(campaign.capture.settings(), rig)
    if problems:
        raise CampaignError(f"{source}: campaign does not fit the rig:\n  " + "\n  ".join(problems))


_UNION_TAGS = {"pattern": CentredPattern, "explicit": ExplicitViews}


def campaign_sha256(path: str | Path) -> str:
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()


def parse_campaign(data: Any, source: str | Path = "<campaign>") -> Campaign:
    return parse_model(data, Campaign, source=source, what="campaign", error=CampaignError, tags=_UNION_TAGS)


def load_campaign(path: str | Path) -> Campaign:
    """Read and validate a campaign file; raise CampaignError with one clear message."""
    return parse_campaign(read_yaml(path, "campaign", CampaignError), path)
