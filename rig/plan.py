"""Campaign → plan: incidence series, viewing directions, motor angles, skipped points.

A plan is data. Every planned direction gets a stable `point_id`
(`<series>-<view>`, from the campaign alone) whether it is measured or
skipped, so ids survive a resume and skipped points can be reported.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

from rig import geometry as geo
from rig.campaign import Campaign, CentredPattern
from rig.motion import move_time_s as trapezoid_time_s
from rig.optics import CameraOptics, roi_inside_spot
from rig.rigconfig import RigConfig

#: Directions closer than this (radians) are the same planned direction.
SAME_DIRECTION_RAD = 1e-9

SKIP_REASONS = {
    "below_horizon": "viewing direction at or below the sample plane (θo ≥ 90°)",
    "beyond_max_view_theta": "θo beyond limits.max_view_theta_deg",
    "occluded_by_lamp": "camera would look into the lamp housing (too close to retroreflection)",
    "axis_limits": "no axis solution inside the configured limits",
    "roi_unlit": "the ROI would not lie entirely inside the lit spot",
}


@dataclass(frozen=True)
class Series:
    index: int
    theta_i_deg: float
    phi_i_deg: float


@dataclass(frozen=True)
class PlannedPoint:
    point_id: str
    series: int
    theta_i_deg: float
    phi_i_deg: float
    theta_o_deg: float
    phi_o_deg: float
    motors_deg: tuple[float, float, float, float]   # stage_vertical, stage_normal, arm_azimuth, arm_polar


@dataclass(frozen=True)
class SkippedPoint:
    point_id: str
    series: int
    theta_i_deg: float
    phi_i_deg: float
    theta_o_deg: float
    phi_o_deg: float
    reason: str


@dataclass(frozen=True)
class Plan:
    series: tuple[Series, ...]
    points: tuple[PlannedPoint, ...]
    skipped: tuple[SkippedPoint, ...]

    @property
    def n_planned(self) -> int:
        return len(self.points) + len(self.skipped)

    def skipped_by_reason(self) -> dict[str, int]:
        return dict(Counter(s.reason for s in self.skipped))


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
    keep = []
    for k, d in enumerate(dirs):
        if not keep or np.all(geo.angle_between(dirs[keep], d) > SAME_DIRECTION_RAD):
            keep.append(k)
    return dirs[keep]


def build_plan(campaign: Campaign, rig: RigConfig) -> Plan:
    """Plan every (incidence, view) pair; leave out, with a reason, what cannot be measured."""
    limits = rig.axes.limits()
    optics = CameraOptics.from_config(rig)
    occlusion_rad = np.arctan2(rig.geometry.lamp_housing_radius_m, rig.geometry.lamp_distance_m)
    max_view_rad = np.radians(campaign.limits.max_view_theta_deg)
    current = (0.0, 0.0, 0.0, 0.0)
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
        reason = np.full(len(wo), "", dtype=object)

        def mark(mask: np.ndarray, why: str) -> None:
            reason[(reason == "") & mask] = why

        mark(wo[:, 2] <= 1e-12, "below_horizon")
        mark(theta_o > max_view_rad + 1e-12, "beyond_max_view_theta")
        mark(geo.angle_between(wo, wi[None, :]) < occlusion_rad, "occluded_by_lamp")
        mark(~np.all(np.isfinite(motors), axis=1), "axis_limits")
        if campaign.limits.skip_roi_unlit:
            ok = np.all(np.isfinite(motors), axis=1)
            lit = np.zeros(len(wo), bool)
            if ok.any():
                m = np.radians(motors[ok])
                lit[ok] = roi_inside_spot(m[:, 0], m[:, 1], m[:, 2], m[:, 3], campaign.capture.roi_px,
                                          optics, rig.geometry.spot_diameter_m / 2)
            mark(~lit, "roi_unlit")

        for k in range(len(wo)):
            pid = f"{series.index:02d}-{k:03d}"
            angles = (series.theta_i_deg, series.phi_i_deg, float(theta_o_deg[k]), float(phi_o_deg[k]))
            if reason[k]:
                skipped.append(SkippedPoint(pid, series.index, *angles, reason[k]))
            else:
                points.append(PlannedPoint(pid, series.index, *angles, tuple(float(x) for x in motors[k])))
        measured = [p for p in points if p.series == series.index]
        if measured:
            current = measured[-1].motors_deg
    return Plan(tuple(series_list), tuple(points), tuple(skipped))


def move_time_s(rig: RigConfig, start_deg: tuple[float, ...], target_deg: tuple[float, ...]) -> float:
    """All four axes start together; the slowest one (plus its settling) sets the time."""
    times = [0.0]
    for name, s, t in zip(geo.AXIS_NAMES, start_deg, target_deg):
        if s != t:
            cfg = getattr(rig.axes, name)
            times.append(trapezoid_time_s(t - s, cfg.speed_deg_s, cfg.accel_deg_s2) + cfg.settle_s)
    return max(times)


def estimate_rig_time_s(plan: Plan, rig: RigConfig, capture_s_per_point: float,
                        start_deg: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0)) -> float:
    """Rig time of the measured points in plan order: moves plus a nominal capture time each."""
    total, here = 0.0, start_deg
    for p in plan.points:
        total += move_time_s(rig, here, p.motors_deg) + capture_s_per_point
        here = p.motors_deg
    return total
