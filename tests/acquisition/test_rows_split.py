"""A row's uncertainty in two parts (issue 34): the calibrations shared by every point, and the rest."""

import dataclasses
import math

import numpy as np
import pytest

from rig.acquisition.capture import PointCapture
from rig.acquisition.rows import Measurement, RowConstants, bracketed_rows, latest_row
from rig.core.values import Window
from rig.physics.budget import CORRELATED_COMPONENTS, lobe_view_u_deg
from rig.physics.geometry import BrdfAngles
from rig.physics.illuminance import IlluminanceEstimate
from rig.physics.static_texture import MIN_PAIRS, StaticTexture
from rig.planning.points import PlannedPoint

L = 100.0
CAMERA_CAL, METER_CAL, FILTER_CAL = 0.02, 0.015, 0.01
CONSTANTS = RowConstants(angle_u_deg=0.01, lobe_view_u_deg=lobe_view_u_deg(0.01, 0.002), grazing_limit_deg=88.0,
                         calibration_u_rel=CAMERA_CAL)


def measurement(rig_time_s: float) -> Measurement:
    """θi = 30°, the ROI known to 0.3 % (noise and texture) ⊕ the camera's 2 % ⊕ a filter's 1 %."""
    u_lum = L * math.sqrt(0.003 ** 2 + CAMERA_CAL ** 2 + FILTER_CAL ** 2)
    capture = PointCapture(
        luminance_cd_m2=L, u_luminance_cd_m2=u_lum, roi_std_cd_m2=1.0, exposures_s=(0.01,), saturated_fraction=0.0,
        flags=(), image_cd_m2=None, roi_window=Window(0, 0, 30, 30), n_frames=1, u_noise_cd_m2=0.001 * L,
        u_dark_cd_m2=0.0, u_texture_cd_m2=math.sqrt(0.003 ** 2 - 0.001 ** 2) * L, capture_time_s=0.01, n_darks=1,
        filter_position=2, transmission=0.1, u_rel_attenuation=FILTER_CAL)
    point = PlannedPoint("s0-p1", 0, 30.0, 0.0, 10.0, 180.0, (0.0, 30.0, 10.0, 180.0))
    angles = BrdfAngles(np.float64(30.0), np.float64(0.0), np.float64(10.0), np.float64(180.0))
    return Measurement(point, (0.0, 30.0, 10.0, 180.0), angles, capture, (), "2026-01-01T00:00:00Z", rig_time_s)


def reading(value_lx: float, t: float) -> IlluminanceEstimate:
    return IlluminanceEstimate(value_lx, 0.002 * value_lx, METER_CAL * value_lx, 5, t)


def check_split(row: dict) -> None:
    f, u = row["brdf_per_sr"], row["u_brdf_per_sr"]
    corr = math.sqrt(CAMERA_CAL ** 2 + METER_CAL ** 2 + FILTER_CAL ** 2)
    assert row["u_brdf_correlated_per_sr"] / f == pytest.approx(corr, rel=1e-9)
    assert math.hypot(row["u_brdf_point_per_sr"], row["u_brdf_correlated_per_sr"]) == pytest.approx(u, rel=1e-12)
    assert row["u_brdf_point_per_sr"] / f < 0.005           # ROI 0.3 %, readings 0.2 %, drift 0.29 %, angle
    assert row["u_rel_meter_calibration"] == pytest.approx(METER_CAL, rel=1e-9)
    budget = [row[c] for c in row if c.startswith("u_rel_")]
    assert math.sqrt(sum(b ** 2 for b in budget)) == pytest.approx(u / f, rel=1e-9)   # each component once
    assert math.sqrt(sum(row[c] ** 2 for c in CORRELATED_COMPONENTS)) == pytest.approx(corr, rel=1e-9)


def test_latest_reading_row_has_calibrations_apart():
    row = latest_row(measurement(5.0), reading(1000.0, 0.0), CONSTANTS)
    assert row["u_rel_illuminance"] == pytest.approx(0.002, rel=1e-9)
    check_split(row)


def test_interpolated_rows_have_calibrations_apart():
    rows = bracketed_rows([measurement(t) for t in (10.0, 50.0)], reading(1000.0, 0.0), reading(1010.0, 60.0),
                          CONSTANTS)
    for row in rows:
        check_split(row)


def test_the_axes_zero_errors_are_shared_and_their_read_back_is_not():
    constants = RowConstants(angle_u_deg=0.01, lobe_view_u_deg=lobe_view_u_deg(0.01, 0.002), grazing_limit_deg=88.0,
                             calibration_u_rel=CAMERA_CAL, readback_u_deg=0.002)
    row = latest_row(measurement(5.0), reading(1000.0, 0.0), constants)
    tan_i = math.tan(math.radians(30.0))
    assert row["u_rel_angle"] == pytest.approx(tan_i * math.radians(0.002), rel=1e-9)
    assert row["u_rel_angle_zero"] == pytest.approx(tan_i * math.radians(math.sqrt(0.01 ** 2 - 0.002 ** 2)), rel=1e-9)
    corr = math.sqrt(CAMERA_CAL ** 2 + METER_CAL ** 2 + FILTER_CAL ** 2 + row["u_rel_angle_zero"] ** 2)
    assert row["u_brdf_correlated_per_sr"] / row["brdf_per_sr"] == pytest.approx(corr, rel=1e-9)
    before = latest_row(measurement(5.0), reading(1000.0, 0.0), CONSTANTS)       # no read-back: all of it differs
    assert before["u_rel_angle_zero"] == 0.0 and before["u_brdf_per_sr"] == pytest.approx(row["u_brdf_per_sr"])


def textured(k: int, static: np.ndarray, rng: np.random.Generator) -> Measurement:
    """Point k of a series that sees the same sample area (the same axes' positions, θo 10°: one block grid) with
    its half vector 4° further each time: a 7 × 7 block pattern of the static grain plus glints of the same power."""
    m = measurement(5.0 + k)
    pattern = static + 0.01 * rng.standard_normal((7, 7))
    angles = BrdfAngles(np.float64(8.0 * k), np.float64(0.0), np.float64(10.0), np.float64(180.0))
    point = dataclasses.replace(m.point, point_id=f"s0-p{k}")
    return dataclasses.replace(m, point=point, angles=angles, motors_deg=(-30.0, 0.0, 50.0, -90.0),
                               capture=dataclasses.replace(m.capture, filter_position=0, transmission=1.0,
                                                           u_rel_attenuation=0.0, roi_pattern=pattern))


def test_the_static_grain_common_to_the_views_moves_to_the_correlated_part():
    """Half the block variance is a grain every view of the area shares: once the run has MIN_PAIRS pairs of
    such views, each row moves that half of its ROI variance (noise and texture) out of the point's own u into
    u_rel_texture_static (correlated); u_brdf_per_sr is unchanged. Before that, nothing moves."""
    rng = np.random.default_rng(3)
    static = 0.01 * rng.standard_normal((7, 7))
    constants = dataclasses.replace(CONSTANTS, texture=StaticTexture())     # a run of its own
    points = [textured(k, static, rng) for k in range(12)]
    rows = [latest_row(m, reading(1000.0, 0.0), constants) for m in points]
    without = dataclasses.replace(points[-1], capture=dataclasses.replace(points[-1].capture, roi_pattern=None))
    plain = latest_row(without, reading(1000.0, 0.0), constants)
    assert rows[0]["u_rel_texture_static"] == 0.0 and constants.texture.pairs >= MIN_PAIRS
    last = rows[-1]
    assert last["u_brdf_per_sr"] == pytest.approx(plain["u_brdf_per_sr"], rel=1e-12)
    block_sq = 0.003 ** 2                                           # u_noise² + u_texture² of `measurement`
    assert last["u_rel_texture_static"] ** 2 == pytest.approx(0.5 * block_sq, rel=0.25)     # one footprint: all common
    assert last["u_rel_texture"] ** 2 + last["u_rel_texture_static"] ** 2 == pytest.approx(
        plain["u_rel_texture"] ** 2, rel=1e-9)
    f = last["brdf_per_sr"]
    assert (last["u_brdf_correlated_per_sr"] / f) ** 2 == pytest.approx(
        (plain["u_brdf_correlated_per_sr"] / f) ** 2 + last["u_rel_texture_static"] ** 2, rel=1e-9)
    assert last["u_brdf_point_per_sr"] < plain["u_brdf_point_per_sr"]
    assert math.hypot(last["u_brdf_point_per_sr"], last["u_brdf_correlated_per_sr"]) == pytest.approx(
        last["u_brdf_per_sr"], rel=1e-12)


def test_a_steep_lobes_angle_error_splits_into_read_back_and_shared_offsets():
    """On a lobe's flank the view's angle errors move f by the lobe's slope times the error: the read-back's part
    differs from point to point (`u_rel_lobe_angle`), the axes' fixed zeros are one offset for every point
    (`u_rel_angle_zero`, with the zeros' tan θi part), and u itself is what it was: each part counted once."""
    constants = dataclasses.replace(CONSTANTS, readback_u_deg=0.002)
    m = measurement(5.0)
    slope_per_footprint, footprint_deg = 2.0, 0.5
    m = dataclasses.replace(m, footprint_deg=footprint_deg,
                            capture=dataclasses.replace(m.capture, lobe_slope_rel=slope_per_footprint))
    row = latest_row(m, reading(1000.0, 0.0), constants)
    per_deg = slope_per_footprint / footprint_deg
    assert row["u_rel_lobe_angle"] == pytest.approx(per_deg * 0.002 * math.sqrt(5), rel=1e-9)
    shared_lobe = per_deg * math.sqrt(constants.lobe_view_u_deg ** 2 - (0.002 * math.sqrt(5)) ** 2)
    tan_part = math.tan(math.radians(30.0)) * math.radians(math.sqrt(0.01 ** 2 - 0.002 ** 2))
    assert row["u_rel_angle_zero"] == pytest.approx(math.hypot(tan_part, shared_lobe), rel=1e-9)
    f, u = row["brdf_per_sr"], row["u_brdf_per_sr"]
    assert math.sqrt(sum(row[c] ** 2 for c in row if c.startswith("u_rel_"))) == pytest.approx(u / f, rel=1e-9)
    assert row["u_brdf_correlated_per_sr"] / f > shared_lobe
