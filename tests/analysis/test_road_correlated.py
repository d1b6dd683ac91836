"""Road quantities carry the shared calibrations apart from the predictor's u (issue 34)."""

import numpy as np
import pytest

from rig.analysis import road
from rig.analysis.prediction import Prediction


class Lambert:
    """f = kd/π everywhere, u 1 % of it (the point-to-point part a weighted fit would give)."""

    method = "closed-form"

    def predict(self, theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg) -> Prediction:
        f = np.broadcast_to(0.5 / np.pi, np.broadcast(theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg).shape)
        return Prediction(f * 1.0, 0.01 * f, np.zeros(f.shape, bool))


class Columns(dict):
    @property
    def columns(self):
        return list(self)


def test_shared_calibration_shifts_every_quantity_by_its_relative_u():
    ds = Columns(u_rel_calibration=np.full(5, 0.02), u_rel_meter_calibration=np.full(5, 0.015))
    rel = road.shared_calibration_u_rel(ds)
    assert rel == pytest.approx(0.025, rel=1e-12)
    doc = road.road_json(road.road_quantities(Lambert(), n=16, correlated_u_rel=rel))
    for key in ("R_L_mcd_m2_lx", "Qd_mcd_m2_lx", "Q0"):
        assert doc["u_correlated"][key] == pytest.approx(0.025 * doc[key], rel=1e-12)
    assert doc["u_R_L_mcd_m2_lx"] == pytest.approx(0.01 * doc["R_L_mcd_m2_lx"], rel=1e-9)   # the predictor's own


def test_a_dataset_without_the_calibration_columns_shares_nothing():
    assert road.shared_calibration_u_rel(Columns(u_rel_noise=np.ones(3))) == 0.0


def test_the_static_grains_common_part_is_shared_too():
    ds = Columns(u_rel_calibration=np.full(5, 0.02), u_rel_meter_calibration=np.full(5, 0.015),
                 u_rel_texture_static=np.array([0.01, 0.01, 0.01, np.nan, 0.01]))
    assert road.shared_calibration_u_rel(ds) == pytest.approx(np.sqrt(0.02 ** 2 + 0.015 ** 2 + 0.01 ** 2), rel=1e-12)
