"""One schema, one set of bounds (issue 9, defect 4): every campaign the validator accepts can be
planned and its capture settings built; values just beyond a bound are refused by the validator.

Values are drawn from the schema's own field metadata (types, ge/gt/le/lt), so the test follows
the schema when a bound changes.
"""

from __future__ import annotations

import math
from typing import Any

import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from pydantic import BaseModel
from shared import _base_type, _bounds, field_strategy

from rig.config.campaign import (
    Campaign,
    CampaignError,
    Capture,
    Illuminance,
    Lamp,
    Limits,
    Suspenders,
    check_campaign_for_rig,
    parse_campaign,
)
from rig.config.capture import CaptureSettings
from rig.config.rigfile import RigConfig
from rig.planning.plan import build_plan, estimate_rig_time_s

SECTIONS: dict[str, type[BaseModel]] = {"capture": Capture, "illuminance": Illuminance, "lamp": Lamp,
                                        "limits": Limits, "suspenders": Suspenders}
RIG = RigConfig()


def section_strategy(model: type[BaseModel]) -> st.SearchStrategy[dict]:
    """A section with any subset of its keys set to in-bounds values."""
    return st.fixed_dictionaries({}, optional={name: field_strategy(model, name) for name in model.model_fields})


angles_theta = st.lists(st.floats(0, 89.9), min_size=1, max_size=2)
angles_phi = st.lists(st.floats(0, 359.9), min_size=1, max_size=2)
incidence = st.lists(st.fixed_dictionaries({"phi": st.floats(0, 359.9), "theta": angles_theta}),
                     min_size=1, max_size=2)
pattern = st.fixed_dictionaries({"centred_on": st.sampled_from(["incidence", "mirror", "normal"]),
                                 "theta": st.lists(st.floats(0, 90), min_size=1, max_size=3),
                                 "phi": st.lists(st.floats(0, 360), min_size=1, max_size=3)})
explicit = st.fixed_dictionaries({"points": st.lists(st.tuples(st.floats(0, 90), st.floats(0, 359.9)),
                                                     min_size=1, max_size=3)})
campaigns = st.fixed_dictionaries(
    {"name": st.just("prop"),
     "sample": st.fixed_dictionaries({"id": st.just("S"), "simulated_brdf": st.fixed_dictionaries(
         {"model": st.just("lambert"), "params": st.fixed_dictionaries({"kd": st.floats(0.01, 1.0)})})}),
     "incidence": incidence,
     "viewing": st.lists(st.one_of(pattern, explicit), min_size=1, max_size=2)},
    optional={key: section_strategy(model) for key, model in SECTIONS.items()}
    | {"ordering": st.sampled_from(["optimised", "table"])})


def _valid(data: dict) -> Campaign | None:
    """The campaign if the validator (schema and rig cross-check) accepts it, else None."""
    try:
        campaign = parse_campaign(data, "prop.yaml")
        check_campaign_for_rig(campaign, RIG, "prop.yaml")
    except CampaignError:
        return None
    return campaign


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(campaigns)
def test_every_valid_campaign_plans_and_captures(data):
    campaign = _valid(data)
    assume(campaign is not None)          # only cross-field rules (e.g. max_frames ≥ frames_per_exposure)
    settings_ = campaign.capture.settings()
    assert isinstance(settings_, CaptureSettings) and settings_.full_frame == campaign.capture.save_images
    plan = build_plan(campaign, RIG)
    rig_time = estimate_rig_time_s(plan, RIG.axes, 0.05)
    assert math.isfinite(rig_time) and rig_time >= 0


@settings(max_examples=60, deadline=None)
@given(section_strategy(Capture))
def test_every_valid_capture_section_builds_settings(section):
    """Defect 4: `capture: {bracket_stops: 0.3}` (and roi_px 4–19) validated, then failed mid-run."""
    try:
        capture = Capture.model_validate(section)
    except ValueError:
        assume(False)
    assert capture.settings().roi_px == capture.roi_px


def _just_outside(model: type[BaseModel]) -> list[tuple[str, Any]]:
    """(field, value) pairs just beyond each numeric bound of `model`."""
    out = []
    for name, field in model.model_fields.items():
        kind, _ = _base_type(field.annotation)
        step = 1 if kind is int else 1e-9
        for bound, value in _bounds(field).items():
            out.append((name, value - (step if bound == "ge" else 0) if bound in ("ge", "gt")
                        else value + (step if bound == "le" else 0)))
    return out


@pytest.mark.parametrize("section, key, value", [(s, k, v) for s, m in SECTIONS.items() for k, v in _just_outside(m)])
def test_values_beyond_a_bound_are_refused(section, key, value):
    base = {"name": "p", "sample": {"id": "S"}, "incidence": [{"phi": 0, "theta": [30]}],
            "viewing": [{"points": [[30, 180]]}]}
    with pytest.raises(CampaignError, match=f"'{section}.{key}'"):
        parse_campaign({**base, section: {key: value}}, "p.yaml")


@pytest.mark.parametrize("section", [{"bracket_stops": 0.3}, {"roi_px": 4}, {"roi_px": 19}])
def test_defect4_capture_values_refused_by_the_schema(section):
    """Before: accepted by the campaign schema, then CaptureSettings raised mid-run (exit 1)."""
    with pytest.raises(CampaignError, match=f"capture.{next(iter(section))}"):
        parse_campaign({"name": "p", "sample": {"id": "S"}, "incidence": [{"phi": 0, "theta": [30]}],
                        "viewing": [{"points": [[30, 180]]}], "capture": section}, "p.yaml")
