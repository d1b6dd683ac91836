"""An adaptive campaign's candidate domain and its first pass (campaign key `sampling`, mode `adaptive`).

In adaptive mode the campaign's tables say *where* the rig may measure, not what to measure in full: each
incidence entry's θ range is filled at its finest step (the paper's 0, 10, …, 80, 85° at φi = 0 becomes 0, 5, …,
85°), each centred pattern gets a ring of views half-way between each two of its rings (`between_rings`: views
the table does not have, where its in-hull error lies), and every view is a candidate at every candidate
incidence. The candidates are
planned like a table campaign (motors, skip reasons, stable ids `<series>-<view>` from the campaign alone), so a
chosen candidate is an ordinary planned point and a resume finds it again by its id.

The first pass (cf. Dupuy & Jakob 2018, who scan retroreflection before anything else) measures the mandatory
pairs and `first_pass_incidences` incidences spread over the main entry's θ range, at each `batch_points` of the
patterns' own views spread over the projected disk by farthest-point sampling, starting next to the
retroreflection and the mirror direction: the interpolant then covers the whole domain, and rig.analysis.adaptive
spends the rest of the budget where it is least certain.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from rig.config.campaign import Campaign, CampaignError, CentredPattern, ExplicitViews, IncidenceSeries, ViewSpec
from rig.config.rigfile import RigConfig
from rig.physics import geometry as geo
from rig.planning.points import Plan, PlannedPoint, PointAngles, SkippedPoint, as_motors, describe_reason
from rig.planning.table import table_plan, viewing_directions

#: Candidate θi closer than this (degrees) to a value already in an entry are the same incidence.
SAME_THETA_DEG = 1e-6


def filled_thetas(thetas: list[float]) -> list[float]:
    """The entry's θ values and its range filled at its finest step (the smallest gap between its values)."""
    values = sorted(set(thetas))
    if len(values) < 2:
        return values
    step = float(np.min(np.diff(values)))
    grid = np.arange(values[0], values[-1] + SAME_THETA_DEG, step)
    extra = [float(t) for t in grid if min(abs(t - v) for v in values) > SAME_THETA_DEG]
    return sorted(values + extra)


def between_rings(viewing: Sequence[ViewSpec]) -> list[ViewSpec]:
    """Per centred pattern, a ring of views half-way between each two of its rings (θ midpoints, the same
    azimuths). The table's in-hull error is set by the spacing of its rings, not of its incidences: on drawn
    samples (synthesised at the planned angles) filling θi at 5° moved the table's p95 by 2 %, these rings halved it
    (docs/sampling.md). They are candidates only: the sampler takes them where the reconstruction needs them."""
    out: list[ViewSpec] = []
    for v in viewing:
        rings = sorted(set(v.theta)) if isinstance(v, CentredPattern) else []
        if len(rings) >= 2:
            out.append(v.model_copy(update={"theta": [(a + b) / 2 for a, b in zip(rings[:-1], rings[1:])]}))
    return out


def candidate_campaign(campaign: Campaign) -> Campaign:
    """The table campaign whose every pair is a candidate: incidence ranges filled, then the views between
    the patterns' rings and the mandatory pairs' incidences and views added (each at the end, so the ids of the
    table's own candidates depend on neither: a series' own pattern views are its first ones)."""
    incidence = [IncidenceSeries(phi=e.phi, theta=filled_thetas(e.theta)) for e in campaign.incidence]
    viewing = list(campaign.viewing) + between_rings(campaign.viewing)
    mandatory = campaign.sampling.mandatory
    if mandatory:
        incidence += [IncidenceSeries(phi=m[1], theta=[m[0]]) for m in mandatory]
        viewing.append(ExplicitViews(points=[(m[2], m[3]) for m in mandatory]))
    return campaign.model_copy(update={"incidence": incidence, "viewing": viewing})


def pattern_ids(campaign: Campaign, candidates: Plan) -> frozenset[str]:
    """Ids of the candidates that are the campaign's own pattern views, not views between its rings: at an
    incidence not measured yet the sampler takes these whole (rig.analysis.adaptive), so that a new incidence's
    hull is the table's. A series' own views come first in its view order (`candidate_campaign`), so they are
    those whose view index is below the number of the campaign's views at that incidence."""
    own = {s.index: len(viewing_directions(campaign, s.theta_i_deg, s.phi_i_deg)) for s in candidates.series}
    return frozenset(p.point_id for p in candidates.points if int(p.point_id.split("-")[1]) < own[p.series])


def candidate_plan(campaign: Campaign, rig: RigConfig) -> Plan:
    """Every candidate in table order, planned (motors) or skipped with its reason, one per isotropic pair
    (`one_per_isotropic_pair`); moves not checked."""
    plan = table_plan(candidate_campaign(campaign), rig)
    return replace(plan, points=tuple(one_per_isotropic_pair(plan.points, set(_mandatory_matches(campaign, plan)))))


def isotropic_key(p: PointAngles) -> tuple[float, float, float]:
    """What an isotropic BRDF's value depends on: θi and the view in the incidence's folded projected disk
    (rig.physics.geometry.disk_coordinates), rounded to 1e-6."""
    x, y = geo.disk_coordinates(np.array([p.theta_o_deg]), np.array([p.phi_o_deg]), np.array([p.phi_i_deg]))[0]
    return round(p.theta_i_deg, 6), round(float(x), 6), round(float(y), 6)


def one_per_isotropic_pair(points: Sequence[PlannedPoint], keep: Collection[str] = ()) -> list[PlannedPoint]:
    """The points less those an isotropic sample gives the same value as an earlier one: a view and its mirror
    image in the plane of incidence (the viewing patterns are symmetric about it), and the same relative geometry
    at another φi (the paper's φi = 23° and 45° series repeat the φi = 0° one). The interpolant, like the models,
    assumes isotropy (rig.analysis.predict), so a second point at one pair would only repeat a measurement;
    measuring both halves of the table costs twice the rig time for the same dataset. Points in `keep` (the
    mandatory pairs) are kept, and their twins dropped instead."""
    taken = {isotropic_key(p) for p in points if p.point_id in keep}
    out = []
    for p in points:
        key = isotropic_key(p)
        if p.point_id in keep:
            out.append(p)
        elif key not in taken:
            taken.add(key)
            out.append(p)
    return out


def _mandatory_matches(campaign: Campaign, plan: Plan) -> list[str]:
    """Ids of the planned points at the mandatory pairs (those the rig can measure)."""
    return [p.point_id for pair in campaign.sampling.mandatory for p in plan.points if _same_pair(p, pair)]


def mandatory_ids(campaign: Campaign, candidates: Plan) -> list[str]:
    """Ids of the planned candidates at the mandatory pairs; CampaignError naming a pair the rig cannot measure."""
    ids = []
    for k, pair in enumerate(campaign.sampling.mandatory):
        match = next((p for p in (*candidates.points, *candidates.skipped) if _same_pair(p, pair)), None)
        if not isinstance(match, PlannedPoint):
            why = describe_reason(match.reason) if isinstance(match, SkippedPoint) else "not planned"
            raise CampaignError(f"key 'sampling.mandatory[{k}]': value {list(pair)} (θi, φi, θo, φo) cannot be "
                                f"measured on this rig: {why}")
        ids.append(match.point_id)
    return ids


def _same_pair(p: PointAngles, pair: tuple[float, float, float, float]) -> bool:
    theta_i, phi_i, theta_o, phi_o = pair
    return (abs(p.theta_i_deg - theta_i) < 1e-6 and _same_azimuth(p.phi_i_deg, phi_i, theta_i)
            and abs(p.theta_o_deg - theta_o) < 1e-6 and _same_azimuth(p.phi_o_deg, phi_o, theta_o))


def _same_azimuth(a_deg: float, b_deg: float, theta_deg: float) -> bool:
    return theta_deg < 1e-9 or abs((a_deg - b_deg + 180.0) % 360.0 - 180.0) < 1e-6


def first_pass_thetas(campaign: Campaign, n: int) -> list[float]:
    """n incidences of the main (first) entry spread evenly over its range, each snapped to a candidate θ."""
    thetas = np.array(filled_thetas(campaign.incidence[0].theta))
    wanted = np.linspace(thetas[0], thetas[-1], n)
    return sorted({float(thetas[np.argmin(np.abs(thetas - w))]) for w in wanted})


def spread_views(points: list[PlannedPoint], k: int) -> list[PlannedPoint]:
    """k of one incidence's candidates spread over the projected disk: the ones nearest retroreflection and the
    mirror direction first, then each next one farthest from those chosen (farthest-point sampling)."""
    if len(points) <= k:
        return list(points)
    p0 = points[0]
    xy = geo.disk_coordinates(np.array([p.theta_o_deg for p in points]), np.array([p.phi_o_deg for p in points]),
                              p0.phi_i_deg)
    s = np.sin(np.radians(p0.theta_i_deg))
    seeds = [int(np.argmin(np.hypot(xy[:, 0] - x, xy[:, 1]))) for x in (s, -s)]   # retro at +sin θi, mirror at −
    chosen = list(dict.fromkeys(seeds))
    gap = np.min(np.hypot(*(xy[:, None, :] - xy[None, chosen, :]).transpose(2, 0, 1)), axis=1)
    while len(chosen) < k:
        nxt = int(np.argmax(gap))
        chosen.append(nxt)
        gap = np.minimum(gap, np.hypot(*(xy - xy[nxt]).T))
    return [points[i] for i in sorted(chosen)]


def first_pass(campaign: Campaign, candidates: Plan) -> list[PlannedPoint]:
    """The mandatory pairs, then `batch_points` spread views of its own patterns (`pattern_ids`) at each first-pass
    incidence of the main entry."""
    spec = campaign.sampling
    by_id = {p.point_id: p for p in candidates.points}
    chosen = [by_id[pid] for pid in mandatory_ids(campaign, candidates)]
    phi_main = float(geo.wrap_360(campaign.incidence[0].phi))
    own = pattern_ids(campaign, candidates)
    for theta in first_pass_thetas(campaign, spec.first_pass_incidences):
        here = [p for p in candidates.points if p.point_id in own and abs(p.theta_i_deg - theta) < SAME_THETA_DEG
                and (theta < SAME_THETA_DEG or abs(p.phi_i_deg - phi_main) < SAME_THETA_DEG)]
        chosen += [p for p in spread_views(here, spec.batch_points) if p not in chosen]
    return chosen


def logged_points(candidates: Plan, logged: Sequence[Mapping[str, Any]]) -> list[PlannedPoint]:
    """The points of logged `adaptive_batch` events, in their order, with the motors the batch planned."""
    by_id = {p.point_id: p for p in candidates.points}
    out = []
    for event in logged:
        for pid, motors in zip(event["points"], event["motors_deg"]):
            out.append(replace(by_id[pid], motors_deg=as_motors(motors)))
    return out
