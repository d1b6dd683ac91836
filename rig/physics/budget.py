"""GUM uncertainty budget: per-point relative components and the campaign's summary table.

Each brdf.csv row carries the relative standard uncertainties (k = 1) of its
components; their root sum of squares matches u_brdf_per_sr / brdf_per_sr
(the block-based ROI uncertainty already holds noise and texture together).
The manifest gets, per component, how large it typically is and how much of
the combined variance it makes, largest first, so a lab sees what to improve.

Components are of two kinds (docs/uncertainty.md). The calibrations (the camera's luminance coefficient,
the meter head's factor, a filter's transmission) are one error shared by every point they serve: they
shift the whole dataset together and are CORRELATED_COMPONENTS. The rest differ from point to point. A
row gives both parts (`u_brdf_point_per_sr`, `u_brdf_correlated_per_sr`; their quadrature sum is
u_brdf_per_sr): the point-to-point part is what weights a fit and what the scatter between points is
compared with; the correlated part moves every fitted parameter and road quantity at once.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numpy as np

BUDGET_COLUMNS = {
    "u_rel_noise": "camera shot and read noise of the ROI mean (HDR merge)",
    "u_rel_dark": "noise of the subtracted dark frame(s)",
    "u_rel_texture": "ROI non-uniformity: sample texture and glints (block means about the lobe, minus noise, "
                     "their neighbours' correlation pooled over the run), less its part common to "
                     "the campaign",
    "u_rel_lobe": "the lobe's curvature over the view footprint: its correction to the ROI centre, or on a clear "
                  "slope the bias the fit estimates but cannot resolve, left uncorrected",
    "u_rel_lobe_angle": "the axes' read-back errors through the lobe's measured slope (steep lobes only)",
    "u_rel_calibration": "luminance calibration of the camera",
    "u_rel_attenuation": "transmission of the neutral-density filter in the beam (its calibration)",
    "u_rel_illuminance": "E⊥: meter readings (repeatability, range)",
    "u_rel_meter_calibration": "E⊥: the meter head's calibration factor (its certificate)",
    "u_rel_drift": "lamp drift between E⊥ readings",
    "u_rel_angle": "incidence angle, through tan θi: the axes' read-back, which differs from point to point",
    "u_rel_angle_zero": "the axes' fixed zero errors (or the specular alignment's), through tan θi and a steep "
                        "lobe's slope, shared by every point",
    "u_rel_texture_static": "ROI texture: the sample's static grain, seen alike from every view of the same area, "
                            "and the glints views of nearby half vectors share, their part common to the campaign "
                            "(rig.physics.static_texture)",
}
#: Components that are one error for every point they serve: a calibration certificate's (camera, meter
#: head) for the whole campaign, a filter's transmission for every point taken through that filter, the axes'
#: zero errors for every point (through tan θi, so not one relative shift but one error δ), the sample's static
#: grain for every view of the same area (the ROI's texture: rig.physics.static_texture).
CORRELATED_COMPONENTS = ("u_rel_calibration", "u_rel_meter_calibration", "u_rel_attenuation", "u_rel_angle_zero",
                         "u_rel_texture_static")
#: The two parts of u_brdf_per_sr, in brdf.csv after the budget (absolute, 1/sr).
SPLIT_COLUMNS = {
    "u_brdf_point_per_sr": "point-to-point part of u_brdf_per_sr: every component but the correlated ones",
    "u_brdf_correlated_per_sr": "correlated part: the calibrations shared by many points (CORRELATED_COMPONENTS)",
}
#: What the report, the monitor and dataset.json say where a calibration's u is not stated in the rig file.
NOT_STATED = "calibration u not stated: excluded"


#: Standard uncertainty of the view direction relative to a specular lobe's axis, in units of the per-axis
#: angle uncertainty: the arm's two axes move ωo by up to u each, the stage's two tilt the sample and so
#: move the mirror direction against ωo by up to 2u each; 1 + 1 + 4 + 4 = 10 u² over the 2-D offset, half of
#: it along the lobe's slope.
LOBE_ANGLE_GAIN = math.sqrt(5.0)


def lobe_view_u_deg(angle_u_deg: float, readback_u_deg: float, alignment_u_deg: float | None = None) -> float:
    """Standard uncertainty (degrees) of the view direction relative to a specular lobe's axis.

    Unaligned, the four axes' position errors (`angle_u_deg` each) add up as LOBE_ANGLE_GAIN says.
    Aligned on the sample's specular peak (rig.acquisition.alignment), their fixed parts (zeros, the
    sample's mounting tilt) are measured, to the alignment's own uncertainty, which already holds all
    axes; what varies from point to point is the axes' read-back (`readback_u_deg` each), combined alike.
    """
    if alignment_u_deg is None:
        return angle_u_deg * LOBE_ANGLE_GAIN
    return math.hypot(alignment_u_deg, readback_u_deg * LOBE_ANGLE_GAIN)


def lobe_view_readback_u_deg(view_u_deg: float, angle_u_deg: float, readback_u_deg: float | None) -> float:
    """The part of `view_u_deg` (`lobe_view_u_deg`) that differs from point to point: the axes' read-back
    (`readback_u_deg` each, None: all of the angle u differs), combined as LOBE_ANGLE_GAIN says. The rest, the
    axes' fixed zeros or the specular alignment's error, is the same at every point: through a lobe's slope it
    moves each point by its own slope times one shared offset, a correlated error (`u_rel_angle_zero`)."""
    if readback_u_deg is None:
        return view_u_deg
    return min(min(readback_u_deg, angle_u_deg) * LOBE_ANGLE_GAIN, view_u_deg)


def lobe_angle_u_rel(slope_rel: float, footprint_deg: float, view_u_deg: float) -> float:
    """Relative u of a point on a steep lobe from the axes' angle errors: the lobe's log-slope measured over
    the ROI (per footprint, rig.physics.footprint) per degree, times the view direction's uncertainty
    relative to the lobe (`lobe_view_u_deg`). 0 without a measured slope or footprint (a flat or diffuse
    ROI: the fit resolves no lobe)."""
    if footprint_deg <= 0:
        return 0.0
    return slope_rel / footprint_deg * view_u_deg


def point_budget(*, luminance_cd_m2: float, u_luminance_cd_m2: float, u_noise_cd_m2: float, u_dark_cd_m2: float,
                 u_texture_cd_m2: float, u_lobe_cd_m2: float, lobe_angle_u_rel: float, calibration_u_rel: float,
                 attenuation_u_rel: float,
                 e_perp_lx: float, u_e_perp_lx: float, u_drift_lx: float, theta_i_deg: float,
                 angle_u_deg: float, u_meter_cal_lx: float = 0.0,
                 readback_u_deg: float | None = None, u_texture_static_cd_m2: float = 0.0,
                 lobe_angle_shared_u_rel: float = 0.0) -> dict[str, float]:
    """The relative components (BUDGET_COLUMNS) of one point's BRDF uncertainty.

    The camera parts are relative to the luminance, or to its uncertainty where the ROI is
    (nearly) black, so that an unlit point does not divide by zero. The dark frames' noise is
    taken out of the merge noise (u_noise² = u_frames² + u_dark²), and the drift and the meter's
    calibration (`u_meter_cal_lx`) out of u(E⊥), so that each appears once. The incidence angle's u
    (`angle_u_deg`) splits into its read-back part (`readback_u_deg`, None: all of it) and the fixed zero
    errors' rest. `u_texture_static_cd_m2`: the texture's part common to the campaign (static grain, shared glints)
    (rig.physics.static_texture), apart from `u_texture_cd_m2`, the rest. On a steep lobe the view's angle errors
    split alike: `lobe_angle_u_rel` the read-back's part, `lobe_angle_shared_u_rel` the fixed offsets' (zeros or
    the specular alignment's error, `lobe_view_readback_u_deg`), which joins the zero errors' component.
    """
    readback = angle_u_deg if readback_u_deg is None else min(readback_u_deg, angle_u_deg)
    tan_i = math.tan(math.radians(min(theta_i_deg, 89.9999)))
    lum = max(abs(luminance_cd_m2), u_luminance_cd_m2, 1e-30)
    return {
        "u_rel_noise": math.sqrt(max(u_noise_cd_m2 ** 2 - u_dark_cd_m2 ** 2, 0.0)) / lum,
        "u_rel_dark": u_dark_cd_m2 / lum,
        "u_rel_texture": u_texture_cd_m2 / lum,
        "u_rel_lobe": u_lobe_cd_m2 / lum,
        "u_rel_lobe_angle": lobe_angle_u_rel,
        "u_rel_calibration": calibration_u_rel,
        "u_rel_attenuation": attenuation_u_rel,
        "u_rel_illuminance": math.sqrt(max(u_e_perp_lx ** 2 - u_drift_lx ** 2 - u_meter_cal_lx ** 2, 0.0)) / e_perp_lx,
        "u_rel_meter_calibration": u_meter_cal_lx / e_perp_lx,
        "u_rel_drift": u_drift_lx / e_perp_lx,
        "u_rel_angle": tan_i * math.radians(readback),
        "u_rel_angle_zero": math.hypot(tan_i * math.radians(math.sqrt(angle_u_deg ** 2 - readback ** 2)),
                                       lobe_angle_shared_u_rel),
        "u_rel_texture_static": u_texture_static_cd_m2 / lum,
    }


def split_u(budget: Mapping[str, float], brdf_per_sr: float, u_brdf_per_sr: float) -> dict[str, float]:
    """The SPLIT_COLUMNS of a row: its correlated part from the budget's correlated components, the
    point-to-point part the rest of u_brdf_per_sr (so that the two add in quadrature to it exactly)."""
    u_corr = math.sqrt(sum(budget.get(c, 0.0) ** 2 for c in CORRELATED_COMPONENTS)) * abs(brdf_per_sr)
    u_corr = min(u_corr, u_brdf_per_sr)
    return {"u_brdf_point_per_sr": math.sqrt(u_brdf_per_sr ** 2 - u_corr ** 2), "u_brdf_correlated_per_sr": u_corr}


def campaign_budget(rows: Sequence[Mapping[str, float]], columns: Mapping[str, str]) -> list[dict]:
    """Per component: median and 95th percentile of its relative u, its median share of u², and whether it is
    shared by the points (`correlated`, CORRELATED_COMPONENTS). A component no row gives (an empty cell, or a
    dataset written before it existed) is left out."""
    if not rows:
        return []
    comp = {c: np.array([_number(r.get(c)) for r in rows]) for c in columns}
    comp = {c: np.nan_to_num(v) for c, v in comp.items() if np.any(np.isfinite(v))}
    total_sq = np.sum([v ** 2 for v in comp.values()], axis=0)
    total_sq = np.where(total_sq > 0, total_sq, 1.0)
    table = [{"component": c, "meaning": columns[c], "correlated": c in CORRELATED_COMPONENTS,
              "median_u_rel": float(np.median(v)), "p95_u_rel": float(np.percentile(v, 95)),
              "median_share_of_variance": float(np.median(v ** 2 / total_sq))}
             for c, v in comp.items()]
    return sorted(table, key=lambda row: -row["median_share_of_variance"])


#: The budget component each calibration key of a rig file feeds (rig.config.stated_u).
NOT_STATED_COMPONENT = {"camera.calibration_u_rel": "u_rel_calibration",
                        "meter.calibration_u_rel": "u_rel_meter_calibration", "attenuator.filters": "u_rel_attenuation"}


def not_stated(manifest: Mapping) -> tuple[str, ...]:
    """The calibration u the run's rig file did not state (its `uncertainty_not_stated`, in the manifest)."""
    rig = manifest.get("rig")
    config = rig.get("config") if isinstance(rig, Mapping) else None
    keys = config.get("uncertainty_not_stated") if isinstance(config, Mapping) else None
    return tuple(str(k) for k in keys) if isinstance(keys, list | tuple) else ()


def mark_not_stated(table: list[dict], keys: Sequence[str]) -> list[dict]:
    """The campaign budget with NOT_STATED in the meaning of each component a rig file left without its u
    (used as 0: a silent 0 would pass for an exact calibration)."""
    components = {NOT_STATED_COMPONENT[k.partition("[")[0]]: k for k in keys if k.partition("[")[0] in
                  NOT_STATED_COMPONENT}
    return [{**row, "meaning": f"{row['meaning']} — {NOT_STATED} ({components[row['component']]})"}
            if row["component"] in components else row for row in table]


def _number(value: object) -> float:
    """A budget cell as a float; NaN where it is empty or missing."""
    try:
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return math.nan
