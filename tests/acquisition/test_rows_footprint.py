"""brdf.csv rows carry the view footprint and the lobe correction, and the budget still adds up."""

import math
from dataclasses import replace

import numpy as np
import pytest

from rig.acquisition.capture import PointCapture
from rig.acquisition.rows import Measurement, RowConstants, brdf_row
from rig.core.values import Window
from rig.data.dataset_format import BRDF_COLUMNS, UNITS
from rig.physics.budget import BUDGET_COLUMNS, LOBE_ANGLE_GAIN, lobe_view_u_deg
from rig.physics.geometry import BrdfAngles
from rig.planning.points import PlannedPoint

E_PERP_LX = 1000.0
LUMINANCE = 300.0
CONSTANTS = RowConstants(angle_u_deg=0.1, lobe_view_u_deg=lobe_view_u_deg(0.1, 0.01), grazing_limit_deg=88.0,
                         calibration_u_rel=0.02)
#: Camera parts of a glossy point's ROI, relative: noise (of which dark), texture, lobe correction.
NOISE, DARK, TEXTURE, LOBE = 0.004, 0.002, 0.003, 0.005
#: ln f changes by 0.4 across the footprint's half-angle on this flank.
SLOPE = 0.4


def glossy_measurement() -> Measurement:
    """A point whose ROI mean was corrected for a lobe 2 % high, its u_luminance the sum of its parts."""
    u_lum = LUMINANCE * math.sqrt(NOISE ** 2 + TEXTURE ** 2 + LOBE ** 2 + CONSTANTS.calibration_u_rel ** 2)
    capture = PointCapture(
        luminance_cd_m2=LUMINANCE, u_luminance_cd_m2=u_lum, roi_std_cd_m2=0.1 * LUMINANCE,
        exposures_s=(0.01,), saturated_fraction=0.0, flags=("narrow_lobe",), image_cd_m2=None,
        roi_window=Window(660, 485, 70, 70), n_frames=1, u_noise_cd_m2=NOISE * LUMINANCE,
        u_dark_cd_m2=DARK * LUMINANCE, u_texture_cd_m2=TEXTURE * LUMINANCE, capture_time_s=0.02, n_darks=1,
        lobe_bias_rel=0.02, u_lobe_cd_m2=LOBE * LUMINANCE, lobe_width_rel=0.8, lobe_slope_rel=SLOPE)
    point = PlannedPoint("s0-p1", 0, 30.0, 0.0, 31.0, 180.0, (0.0, 30.0, 31.0, 180.0))
    angles = BrdfAngles(np.float64(30.0), np.float64(0.0), np.float64(31.0), np.float64(180.0))
    return Measurement(point, (0.0, 30.0, 31.0, 180.0), angles, capture, capture.flags, "2026-01-01T00:00:00Z",
                       5.0, footprint_deg=0.37)


def test_row_has_the_footprint_columns():
    row = brdf_row(glossy_measurement(), E_PERP_LX, 10.0, 0.0, CONSTANTS)
    assert set(row) == set(BRDF_COLUMNS)
    assert row["footprint_deg"] == 0.37 and row["lobe_bias_rel"] == 0.02
    assert row["lobe_width_deg"] == pytest.approx(0.8 * 0.37, rel=1e-12)
    assert row["u_rel_lobe"] == pytest.approx(LOBE, rel=1e-12) and row["u_rel_texture"] == pytest.approx(TEXTURE)
    assert "narrow_lobe" in row["flags"].split(";")
    assert UNITS["footprint_deg"] == "deg" and UNITS["lobe_width_deg"] == "deg"


def test_lobe_slope_turns_the_angle_uncertainty_into_a_component():
    row = brdf_row(glossy_measurement(), E_PERP_LX, 10.0, 0.0, CONSTANTS)
    assert row["u_rel_lobe_angle"] == pytest.approx(SLOPE / 0.37 * 0.1 * LOBE_ANGLE_GAIN, rel=1e-12)
    assert row["u_luminance_cd_m2"] < row["u_rel_lobe_angle"] * LUMINANCE     # an angle effect, not the camera's
    without = brdf_row(replace(glossy_measurement(), footprint_deg=0.0), E_PERP_LX, 10.0, 0.0, CONSTANTS)
    assert without["u_rel_lobe_angle"] == 0.0 and without["u_brdf_per_sr"] < row["u_brdf_per_sr"]


def test_budget_components_add_up_to_the_combined_uncertainty():
    row = brdf_row(glossy_measurement(), E_PERP_LX, 10.0, 0.0, CONSTANTS)
    rss = math.sqrt(sum(row[c] ** 2 for c in BUDGET_COLUMNS))
    assert rss == pytest.approx(row["u_brdf_per_sr"] / row["brdf_per_sr"], rel=1e-9)
