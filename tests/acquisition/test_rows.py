"""Rows from a measurement and E⊥ (rig.acquisition.rows), against closed-form values."""

import math

import numpy as np
import pytest

from rig.acquisition.capture import PointCapture
from rig.acquisition.rows import Measurement, RowConstants, bracketed_rows, brdf_row
from rig.core.values import Window
from rig.physics.budget import BUDGET_COLUMNS, lobe_view_u_deg
from rig.physics.geometry import BrdfAngles
from rig.physics.illuminance import IlluminanceEstimate
from rig.planning.points import PlannedPoint

KD = 0.5
THETA_I_DEG = 60.0
E_PERP_LX = 1000.0
#: A Lambertian sample lit at θi: L = kd/π · E⊥ cos θi, so f = L / (E⊥ cos θi) = kd/π.
LUMINANCE = KD / math.pi * E_PERP_LX * math.cos(math.radians(THETA_I_DEG))
CONSTANTS = RowConstants(angle_u_deg=0.1, lobe_view_u_deg=lobe_view_u_deg(0.1, 0.01), grazing_limit_deg=88.0,
                         calibration_u_rel=0.03)


def measurement(rig_time_s: float = 5.0) -> Measurement:
    """A point at θi = 60° whose ROI luminance is known to 1 % (noise 0.5 % of which dark 0.3 %)."""
    capture = PointCapture(
        luminance_cd_m2=LUMINANCE, u_luminance_cd_m2=0.01 * LUMINANCE, roi_std_cd_m2=0.02 * LUMINANCE,
        exposures_s=(0.01, 0.04), saturated_fraction=0.0, flags=(), image_cd_m2=None,
        roi_window=Window(10, 20, 30, 30), n_frames=4, u_noise_cd_m2=0.005 * LUMINANCE,
        u_dark_cd_m2=0.003 * LUMINANCE, u_texture_cd_m2=0.002 * LUMINANCE, capture_time_s=0.06, n_darks=2)
    point = PlannedPoint("s0-p1", 0, THETA_I_DEG, 0.0, 30.0, 180.0, (0.0, 60.0, 30.0, 180.0))
    angles = BrdfAngles(np.float64(THETA_I_DEG), np.float64(0.0), np.float64(30.0), np.float64(180.0))
    return Measurement(point, (0.0, 60.0, 30.0, 180.0), angles, capture, ("retried",), "2026-01-01T00:00:00Z",
                       rig_time_s)


def test_row_of_a_lambertian_point_matches_the_closed_form():
    u_e_lx, u_drift_lx = 0.02 * E_PERP_LX, 0.01 * E_PERP_LX
    row = brdf_row(measurement(), E_PERP_LX, u_e_lx, u_drift_lx, CONSTANTS)
    assert row["brdf_per_sr"] == pytest.approx(KD / math.pi, rel=1e-12)
    assert row["illuminance_lx"] == pytest.approx(E_PERP_LX * 0.5, rel=1e-12)
    angle_rel = math.tan(math.radians(THETA_I_DEG)) * math.radians(0.1)
    assert row["u_brdf_per_sr"] / row["brdf_per_sr"] == pytest.approx(math.sqrt(0.01 ** 2 + 0.02 ** 2 + angle_rel ** 2),
                                                                       rel=1e-12)
    assert row["u_rel_noise"] == pytest.approx(0.004, rel=1e-9)               # √(0.005² − 0.003²)
    assert row["u_rel_dark"] == pytest.approx(0.003, rel=1e-12)
    assert row["u_rel_texture"] == pytest.approx(0.002, rel=1e-12)
    assert row["u_rel_calibration"] == pytest.approx(0.03, rel=1e-12)
    assert row["u_rel_illuminance"] == pytest.approx(math.sqrt(3) * 0.01, rel=1e-12)   # √(0.02² − 0.01²)
    assert row["u_rel_drift"] == pytest.approx(0.01, rel=1e-12)
    assert row["u_rel_angle"] == pytest.approx(angle_rel, rel=1e-12)
    assert set(BUDGET_COLUMNS) <= set(row)
    assert row["flags"] == "retried" and row["point_id"] == "s0-p1" and row["exposures_s"] == [0.01, 0.04]
    assert (row["stage_normal_deg"], row["arm_polar_deg"]) == (60.0, 180.0)


def test_grazing_incidence_is_flagged():
    m = measurement()
    grazing = Measurement(m.point, m.motors_deg, BrdfAngles(*(np.float64(a) for a in (89.0, 0.0, 30.0, 180.0))),
                          m.capture, (), m.time_utc, m.rig_time_s)
    assert brdf_row(grazing, E_PERP_LX, 1.0, 0.0, CONSTANTS)["flags"] == "grazing_incidence"


def test_points_between_two_readings_get_e_perp_interpolated_in_rig_time():
    before = IlluminanceEstimate(1000.0, 1.0, 0.0, 5, 0.0)
    after = IlluminanceEstimate(1100.0, 1.0, 0.0, 5, 10.0)
    middle, late = bracketed_rows([measurement(5.0), measurement(10.0)], before, after, CONSTANTS)
    assert middle["illuminance_normal_lx"] == pytest.approx(1050.0, rel=1e-12)
    assert late["illuminance_normal_lx"] == pytest.approx(1100.0, rel=1e-12)
    u_drift_lx = 100.0 / math.sqrt(12.0)                                     # rectangular over the change
    assert middle["u_rel_drift"] == pytest.approx(u_drift_lx / 1050.0, rel=1e-12)
    assert middle["u_illuminance_normal_lx"] == pytest.approx(math.sqrt(0.5 + u_drift_lx ** 2), rel=1e-12)
    assert middle["flags"] == "retried" and middle["illuminance_interpolated"] == 1     # a column, not a flag
    uncorrected, = bracketed_rows([measurement(5.0)], before, None, CONSTANTS)
    assert uncorrected["illuminance_normal_lx"] == pytest.approx(1000.0, rel=1e-12)
    assert uncorrected["u_rel_drift"] == pytest.approx(0.0, abs=1e-15) and uncorrected["flags"] == "retried"
    assert uncorrected["illuminance_interpolated"] == 0
