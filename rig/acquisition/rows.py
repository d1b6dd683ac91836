"""brdf.csv rows from measurements and E⊥ (no device, no file).

A point is measured before the E⊥ reading that closes its interval is taken, so the
engine keeps a `Measurement` and turns it into a row once it knows which E⊥ the point
gets: the last reading alone, or one interpolated between the readings that bracket it
(column `illuminance_interpolated` = 1).

The one state a row depends on besides its measurement is the run's estimate of the sample's static
grain (`RowConstants.texture`): each measurement joins it when its row is first built, and its row
carries the split of the ROI texture known then (rig.physics.static_texture, docs/uncertainty.md).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from rig.acquisition.capture import PointCapture
from rig.physics import geometry as geo
from rig.physics.block_correlation import mean_variances
from rig.physics.budget import lobe_angle_u_rel, lobe_view_readback_u_deg, point_budget, split_u
from rig.physics.illuminance import IlluminanceEstimate, brdf_from_luminance, interpolate
from rig.physics.static_texture import StaticTexture, grid_map, half_vector, usable
from rig.planning.points import PlannedPoint


@dataclass(frozen=True)
class Measurement:
    """Everything measured at one point, before E⊥ turns it into a BRDF row."""

    point: PlannedPoint
    motors_deg: tuple[float, float, float, float]
    angles: geo.BrdfAngles
    capture: PointCapture
    flags: tuple[str, ...]
    time_utc: str
    rig_time_s: float
    #: Half-angle of the view directions the ROI averages over (rig.physics.footprint.view_footprint_deg).
    footprint_deg: float = 0.0


@dataclass(frozen=True)
class RowConstants:
    """What a row needs besides the measurement and its E⊥: fixed for a run, but for the texture estimate."""

    angle_u_deg: float            # standard uncertainty of the incidence angle
    lobe_view_u_deg: float        # ... of the view direction relative to a specular lobe (budget.lobe_view_u_deg)
    grazing_limit_deg: float      # θi from which a point is flagged grazing_incidence
    calibration_u_rel: float      # relative uncertainty of the camera's luminance calibration
    #: The part of angle_u_deg that differs from one position to the next (geometry.readback_u_deg); the rest,
    #: the axes' fixed zero errors, is shared by every point (u_rel_angle_zero). None: all of it differs.
    readback_u_deg: float | None = None
    #: The run's estimate of the sample's static grain in the ROI texture, from the points whose rows were built
    #: so far (each row is final when written: it carries the split known then; rig.physics.static_texture).
    texture: StaticTexture = field(default_factory=StaticTexture, compare=False)


def brdf_row(m: Measurement, e_perp_lx: float, u_e_perp_lx: float, u_drift_lx: float,
             constants: RowConstants, *, interpolated: bool = False, meter_cal_u_rel: float = 0.0) -> dict[str, Any]:
    """The brdf.csv row of a measurement, given the E⊥ it gets (and how much of u(E⊥) is drift, and the
    meter certificate's relative u, a part of u(E⊥) shared by every point: rig.physics.budget);
    `interpolated`: that E⊥ was interpolated between bracketing readings (a column, not a flag: it is
    the routine correction of `illuminance.correction: interpolate`, not a condition worth a look)."""
    cap, theta_i = m.capture, float(m.angles.theta_i_deg)
    u_texture, u_static, u_lobe = texture_split(m, constants.texture)
    # The ROI's u with its texture (and the lobe correction's share of it) as the run's pooled block
    # correlation has it (texture_split)
    u_roi = float(np.sqrt(max(cap.u_luminance_cd_m2 ** 2 - cap.u_texture_cd_m2 ** 2 - cap.u_lobe_cd_m2 ** 2
                              + u_texture ** 2 + u_static ** 2 + u_lobe ** 2, 0.0)))
    u_angle_lobe = lobe_angle_u_rel(cap.lobe_slope_rel, m.footprint_deg, constants.lobe_view_u_deg)
    u_angle_lobe_point = lobe_angle_u_rel(cap.lobe_slope_rel, m.footprint_deg, lobe_view_readback_u_deg(
        constants.lobe_view_u_deg, constants.angle_u_deg, constants.readback_u_deg))
    u_luminance = float(np.hypot(u_roi, u_angle_lobe * cap.luminance_cd_m2))
    res = brdf_from_luminance(cap.luminance_cd_m2, u_luminance, e_perp_lx, u_e_perp_lx,
                              theta_i, constants.angle_u_deg, grazing_limit_deg=constants.grazing_limit_deg)
    flags = m.flags + (("grazing_incidence",) if res.grazing_incidence else ())
    budget = point_budget(luminance_cd_m2=cap.luminance_cd_m2, u_luminance_cd_m2=u_roi,
                          u_noise_cd_m2=cap.u_noise_cd_m2, u_dark_cd_m2=cap.u_dark_cd_m2,
                          u_texture_cd_m2=u_texture, u_lobe_cd_m2=u_lobe,
                          lobe_angle_u_rel=u_angle_lobe_point,
                          lobe_angle_shared_u_rel=float(np.sqrt(max(u_angle_lobe ** 2 - u_angle_lobe_point ** 2, 0.0))),
                          calibration_u_rel=constants.calibration_u_rel,
                          attenuation_u_rel=cap.u_rel_attenuation,
                          e_perp_lx=e_perp_lx, u_e_perp_lx=u_e_perp_lx, u_drift_lx=u_drift_lx,
                          theta_i_deg=theta_i, angle_u_deg=constants.angle_u_deg,
                          readback_u_deg=constants.readback_u_deg,
                          u_meter_cal_lx=meter_cal_u_rel * e_perp_lx, u_texture_static_cd_m2=u_static)
    return {
        "point_id": m.point.point_id, "series": m.point.series,
        "theta_i_deg": theta_i, "phi_i_deg": float(m.angles.phi_i_deg),
        "theta_o_deg": float(m.angles.theta_o_deg), "phi_o_deg": float(m.angles.phi_o_deg),
        "brdf_per_sr": float(res.brdf_per_sr), "u_brdf_per_sr": float(res.u_brdf_per_sr),
        "luminance_cd_m2": cap.luminance_cd_m2, "u_luminance_cd_m2": u_roi,
        "illuminance_lx": float(res.illuminance_lx), "illuminance_normal_lx": e_perp_lx,
        "stage_vertical_deg": m.motors_deg[0], "stage_normal_deg": m.motors_deg[1],
        "arm_azimuth_deg": m.motors_deg[2], "arm_polar_deg": m.motors_deg[3],
        "exposures_s": list(cap.exposures_s), "saturated_fraction": cap.saturated_fraction,
        "flags": ";".join(dict.fromkeys(flags)), "time_utc": m.time_utc, "rig_time_s": m.rig_time_s,
        "u_illuminance_normal_lx": u_e_perp_lx, "roi_std_cd_m2": cap.roi_std_cd_m2,
        "n_frames": cap.n_frames, "capture_time_s": cap.capture_time_s,
        "filter_position": cap.filter_position, "filter_transmission": cap.transmission,
        "footprint_deg": m.footprint_deg, "lobe_bias_rel": cap.lobe_bias_rel,
        "lobe_width_deg": cap.lobe_width_rel * m.footprint_deg, **budget,
        "illuminance_interpolated": int(interpolated),
        **split_u(budget, float(res.brdf_per_sr), float(res.u_brdf_per_sr)),
    }


def texture_split(m: Measurement, texture: StaticTexture) -> tuple[float, float, float]:
    """The point's texture u (cd/m²) without its part common to the campaign, that part, and the lobe correction's
    u without its share of that part.

    The point's pattern joins the run's estimates first. Its texture is its independent-block variance times
    the run's pooled inflation for its footprint (the neighbouring blocks' correlation, rig.physics.
    block_correlation), less the noise; while too few views were seen, the ROI's own block u. Where the lobe is
    corrected, the centre value weighs the blocks by `lobe_weights`, not evenly: what that adds to the texture's
    variance, with the same pooled covariances, is the lobe correction's u (else the capture's).

    The block variance (relative) joins the static grain's estimate. The part of the whole (texture and lobe) that
    the campaign's mean texture error takes with it (`common_variance`: the static grain's, and the glints views
    of nearby half vectors share) leaves the texture's u first, then the lobe's; where it is negative (a view that
    shares none of the glints most views share varies about their mean by more than its own texture) it adds to the
    texture's u. Before the estimate has its minimum of view pairs (or without a pattern, or for an edge-on view)
    nothing moves."""
    cap, grid = m.capture, grid_map(m.motors_deg)
    if cap.roi_pattern is None or not usable(grid) or cap.luminance_cd_m2 <= 0:
        return cap.u_texture_cd_m2, 0.0, cap.u_lobe_cd_m2
    lum_sq, area = cap.luminance_cd_m2 ** 2, abs(float(np.linalg.det(grid)))
    quadratic = cap.roi_pattern_quadratic
    texture.blocks.observe(m.point.point_id, cap.roi_pattern, area, quadratic=quadratic)
    inflation = texture.blocks.inflation(area, cap.roi_pattern.shape)
    independent = mean_variances(cap.roi_pattern, quadratic=quadratic)[1]
    texture_sq = cap.u_texture_cd_m2 ** 2 if inflation is None else max(
        independent * inflation * lum_sq - cap.u_noise_cd_m2 ** 2, 0.0)
    centre = None if cap.lobe_weights is None or inflation is None else texture.blocks.weighted_variance(
        area, cap.lobe_weights)
    lobe_sq = cap.u_lobe_cd_m2 ** 2 if centre is None or inflation is None else max(
        independent * (centre * cap.roi_pattern.size - inflation), 0.0) * lum_sq
    half = half_vector(float(m.angles.theta_i_deg), float(m.angles.phi_i_deg), float(m.angles.theta_o_deg),
                       float(m.angles.phi_o_deg))
    texture.observe(m.point.point_id, cap.roi_pattern, grid, half, (cap.u_noise_cd_m2 ** 2 + texture_sq) / lum_sq)
    whole_sq = texture_sq + lobe_sq
    common_sq = min(texture.common_variance(m.point.point_id, grid, half, whole_sq / lum_sq) * lum_sq, whole_sq)
    lobe_common_sq = max(common_sq - texture_sq, 0.0)
    return (float(np.sqrt(texture_sq - common_sq + lobe_common_sq)), float(np.sqrt(max(common_sq, 0.0))),
            float(np.sqrt(lobe_sq - lobe_common_sq)))


def latest_row(m: Measurement, reading: IlluminanceEstimate, constants: RowConstants) -> dict[str, Any]:
    """The row with the E⊥ of the last reading, uncorrected (no drift part)."""
    return brdf_row(m, reading.value_lx, reading.u_lx, 0.0, constants, meter_cal_u_rel=_cal_rel(reading))


def bracketed_rows(measurements: Sequence[Measurement], before: IlluminanceEstimate,
                   after: IlluminanceEstimate | None, constants: RowConstants) -> list[dict[str, Any]]:
    """Rows of the points measured between two readings, E⊥ interpolated in rig time between them
    (`illuminance_interpolated` = 1); without `after` (no closing reading) each keeps `before`'s E⊥."""
    if after is None:
        return [latest_row(m, before, constants) for m in measurements]
    e = interpolate(before, after, np.array([m.rig_time_s for m in measurements]))
    return [brdf_row(m, float(e.value_lx[k]), float(e.u_lx[k]), float(e.u_drift_lx[k]), constants,
                     interpolated=True, meter_cal_u_rel=_cal_rel(before))
            for k, m in enumerate(measurements)]


def _cal_rel(reading: IlluminanceEstimate) -> float:
    """The meter certificate's relative u in a reading (the same for every reading of a run)."""
    return reading.u_cal_lx / reading.value_lx if reading.value_lx > 0 else 0.0
