"""Rows from a measurement and E⊥ (rig.acquisition.rows), against closed-form values."""

import math

import numpy as np
import pytest
from shared import CONSTANTS, E_PERP_LX, KD, THETA_I_DEG, measurement

from rig.acquisition.rows import Measurement, bracketed_rows, brdf_row
from rig.physics.budget import BUDGET_COLUMNS
from rig.physics.geometry import BrdfAngles
from rig.physics.illuminance import IlluminanceEstimate


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
