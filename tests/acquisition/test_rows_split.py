"""A row's uncertainty in two parts (issue 34): the calibrations shared by every point, and the rest."""

import math

import numpy as np
import pytest

from rig.acquisition.capture import PointCapture
from rig.acquisition.rows import Measurement, RowConstants, bracketed_rows, latest_row
from rig.core.values import Window
from rig.physics.budget import CORRELATED_COMPONENTS, lobe_view_u_deg
from rig.physics.geometry import BrdfAngles
from rig.physics.illuminance import IlluminanceEstimate
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
