"""A table campaign's points: incidence series, viewing directions, motor angles and skip reasons.

Every planned direction gets a stable `point_id` (`<series>-<view>`, from the campaign alone) whether it is
measured or skipped, so ids survive a resume and skipped points can be reported. Repeated views are found with
a k-d tree, so the work grows linearly with the points (tests/planning/test_plan_scaling.py counts it).
rig.planning.plan puts the points in order and checks the moves.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from scipy.spatial import cKDTree

from rig.config.campaign import Campaign, CentredPattern
from rig.config.rigfile import RigConfig, camera_optics
from rig.config.zones import ForbiddenZone
from rig.physics import geometry as geo
from rig.physics.optics import roi_inside_spot
from rig.planning.collisions import zone_at, zones_of
from rig.planning.ordering import START_DEG, arm_branches
from rig.planning.points import Plan, PlannedPoint, Series, SkippedPoint, as_motors

#: Directions closer than this (radians) are the same planned direction.
SAME_DIRECTION_RAD = 1e-9


def incidence_series(campaign: Campaign) -> list[Series]:
    """Table 1 order: one series per (θi, φi), duplicates removed."""
    seen: set[tuple[float, float]] = set()
    out: list[Series] = []
    for entry in campaign.incidence:
        for theta in entry.theta:
            phi = float(geo.wrap_360(entry.phi))
            key = (round(theta, 9), round(phi, 9) if theta > 0 else 0.0)
            if key not in seen:
                seen.add(key)
                out.append(Series(len(out), float(theta), phi))
    return out


def viewing_directions(campaign: Campaign, theta_i_deg: float, phi_i_deg: float) -> np.ndarray:
    """Union of the campaign's viewing patterns for one incidence, SCS unit vectors (M, 3).

    Order: patterns in file order, θ-major within a pattern; repeats removed.
    """
    wi = geo.sph_to_vec(np.radians(theta_i_deg), np.radians(phi_i_deg))
    centres = {"incidence": wi, "mirror": geo.mirror_direction(wi), "normal": np.array([0.0, 0.0, 1.0])}
    chunks = []
    for spec in campaign.viewing:
        if isinstance(spec, CentredPattern):
            th, ph = np.meshgrid(np.radians(spec.theta), np.radians(spec.phi), indexing="ij")
            chunks.append(geo.centre_pattern(th.ravel(), ph.ravel(), centres[spec.centred_on]))
        else:
            pts = np.radians(np.asarray(spec.points, float))
            chunks.append(geo.sph_to_vec(pts[:, 0], pts[:, 1]))
    dirs = np.concatenate(chunks)
    return dirs[_first_of_repeats(dirs)]


def _first_of_repeats(dirs: np.ndarray) -> np.ndarray:
    """Indices of the unit vectors (n, 3) kept in order: each unless an earlier kept one lies within
    SAME_DIRECTION_RAD of it.

    Only the pairs a k-d tree finds closer than a chord of twice that angle are measured (a chord
    never exceeds its angle), so a dense viewing pattern costs O(n log n), not the n² angles of all pairs.
    """
    pairs = cKDTree(dirs).query_pairs(2 * SAME_DIRECTION_RAD, output_type="ndarray")
    pairs = pairs[geo.angle_between(dirs[pairs[:, 0]], dirs[pairs[:, 1]]) <= SAME_DIRECTION_RAD]
    keep = np.ones(len(dirs), bool)
    for earlier, later in sorted(map(tuple, pairs), key=lambda pair: pair[1]):     # i < j per pair
        if keep[earlier]:
            keep[later] = False
    return np.flatnonzero(keep)


def table_plan(campaign: Campaign, rig: RigConfig) -> Plan:
    """Every point in campaign order with its motors, or skipped with a reason; moves not yet checked."""
    limits = rig.axes.limits()
    zones = zones_of(rig)
    optics = camera_optics(rig)
    geometry = rig.geometry
    occlusion_rad = np.arctan2(geometry.lamp_housing_radius_m, geometry.lamp_distance_m)
    max_view_rad = np.radians(campaign.limits.max_view_theta_deg)
    current = START_DEG
    series_list = incidence_series(campaign)
    points: list[PlannedPoint] = []
    skipped: list[SkippedPoint] = []
    for series in series_list:
        wi = geo.sph_to_vec(np.radians(series.theta_i_deg), np.radians(series.phi_i_deg))
        wo = viewing_directions(campaign, series.theta_i_deg, series.phi_i_deg)
        theta_o, phi_o = geo.vec_to_sph(wo)
        theta_o_deg, phi_o_deg = np.degrees(theta_o), np.degrees(phi_o)
        motors = geo.inverse_deg(series.theta_i_deg, series.phi_i_deg, theta_o_deg, phi_o_deg,
                                 limits, current).as_array()
        motors, zone = _outside_zones(motors, limits, zones)
        reason = np.full(len(wo), "", dtype=object)
        _mark(reason, wo[:, 2] <= 1e-12, "below_horizon")
        _mark(reason, theta_o > max_view_rad + 1e-12, "beyond_max_view_theta")
        _mark(reason, geo.angle_between(wo, wi[None, :]) < occlusion_rad, "occluded_by_lamp")
        _mark(reason, ~np.all(np.isfinite(motors), axis=1), "axis_limits")
        _mark(reason, zone != "", "forbidden_zone:" + zone)
        if campaign.limits.skip_roi_unlit:
            ok = np.all(np.isfinite(motors), axis=1)
            lit = np.zeros(len(wo), bool)
            if ok.any():
                m = np.radians(motors[ok])
                lit[ok] = roi_inside_spot(m[:, 0], m[:, 1], m[:, 2], m[:, 3], campaign.capture.roi_px,
                                          optics, geometry.spot_diameter_m / 2)
            _mark(reason, ~lit, "roi_unlit")

        for k in range(len(wo)):
            pid = f"{series.index:02d}-{k:03d}"
            angles = (series.theta_i_deg, series.phi_i_deg, float(theta_o_deg[k]), float(phi_o_deg[k]))
            if reason[k]:
                skipped.append(SkippedPoint(pid, series.index, *angles, reason[k]))
            else:
                points.append(PlannedPoint(pid, series.index, *angles, as_motors(motors[k])))
        if np.any(reason == ""):                # the next series' inverse kinematics starts at its last point
            current = points[-1].motors_deg
    return Plan(tuple(series_list), tuple(points), tuple(skipped))


def _mark(reason: np.ndarray, mask: np.ndarray, why: str | np.ndarray) -> None:
    """Give the points in `mask` that have no skip reason yet the reason `why` (the first reason wins)."""
    free = (reason == "") & mask
    reason[free] = np.broadcast_to(np.asarray(why, dtype=object), reason.shape)[free]


def _outside_zones(motors: np.ndarray, limits: geo.AxisLimits,
                   zones: Sequence[ForbiddenZone]) -> tuple[np.ndarray, np.ndarray]:
    """Motors (n, 4) moved to the other arm branch where they lie in a forbidden zone and that one is
    usable; and the zone (or "") each final position lies in."""
    zone = zone_at(motors, zones)
    twins = arm_branches(motors, limits, zones)[:, 1:]
    usable = np.all(np.isfinite(twins), axis=-1)
    move = (zone != "") & usable.any(axis=1)
    first = twins[np.arange(len(motors)), np.argmax(usable, axis=1)]
    return np.where(move[:, None], first, motors), np.where(move, "", zone)
