"""road.json from degenerate predictions (all zero, constant, 1e300, denormals, infinite u): always a complete,
valid JSON file, with null where a quantity is not finite and `undefined` naming them; written under a temporary
name (issue 30, item 9)."""

import json
import math

import numpy as np
import pytest

from rig.analysis import road
from rig.analysis.prediction import Prediction
from rig.cli.main import main


class Constant:
    """A predictor giving one value and one u everywhere."""

    method = "constant (test)"

    def __init__(self, f: float, u: float):
        self.f, self.u = f, u

    def predict(self, theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg) -> Prediction:
        shape = np.broadcast(*(np.asarray(a, float) for a in (theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg))).shape
        return Prediction(np.full(shape, self.f), np.full(shape, self.u), np.zeros(shape, bool))


def _strict(path):
    """road.json parsed as strict JSON (no NaN or Infinity constants)."""
    def refuse(constant):
        raise AssertionError(f"{constant} in {path}")
    return json.loads(path.read_text(), parse_constant=refuse)


U_ALL = {"u_R_L_mcd_m2_lx", "u_Qd_mcd_m2_lx", "r_table.u_r_x1e4", "u_Q0", "u_S1"}


@pytest.mark.parametrize(("f", "u", "undefined"), [
    (0.0, 0.0, {"S1", "u_S1"}),                                                  # S1 = 0/0
    (0.1, 0.01, set()),                                                          # constant
    (1e300, 1e299, set()),                                                       # large, still finite
    (1e306, 1e305, {"R_L_mcd_m2_lx", "Qd_mcd_m2_lx", "r_table.r_x1e4", "r_table.u_r_x1e4", "S1", "u_S1",
                    "u_correlated.R_L_mcd_m2_lx", "u_correlated.Qd_mcd_m2_lx"}),
    (5e-324, 5e-324, set()),                                                     # denormals
    (0.1, math.inf, U_ALL),                                                      # an undetermined parameter's u
    (math.nan, 0.1, {"R_L_mcd_m2_lx", "Qd_mcd_m2_lx", "r_table.r_x1e4", "Q0", "S1", "u_S1",
                     "u_correlated.R_L_mcd_m2_lx", "u_correlated.Qd_mcd_m2_lx", "u_correlated.Q0"}),
])
def test_degenerate_predictions_give_a_valid_road_json(tmp_path, recwarn, f, u, undefined):
    out = tmp_path / "road.json"
    road.export_road(Constant(f, u), out)
    doc = _strict(out)
    assert set(doc.get("undefined", {}).get("quantities", [])) == undefined
    if "S1" in undefined:
        assert doc["S1"] is None and doc["surface_classes"] == {"R": None, "C": None, "N": None}
        assert doc["surface_classes_within_k2"] == {"R": [], "C": [], "N": []}
    if undefined:
        assert "written as null" in str(recwarn.pop(UserWarning).message)
    assert [p.name for p in tmp_path.iterdir()] == ["road.json"]          # no temporary file left


def test_an_infinite_u_reaches_every_class():
    assert road.classes_within(120.0, math.inf, road.R_L_CLASSES) == list(road.R_L_CLASSES)
    assert road.classes_within(math.nan, 1.0, road.R_L_CLASSES) == []
    assert road.classify(math.nan, road.R_L_CLASSES) is None


def test_the_cli_exports_road_json_of_an_all_zero_sample(cea_dir, tmp_path, capsys):
    """`rig export --format road` on a dataset whose f_r are all 0: exit 0 and a complete road.json."""
    lines = (cea_dir / "retro-gray-tape.alta").read_text().splitlines()
    head, data = [x for x in lines if x.startswith("#")], [x for x in lines if x and not x.startswith("#")]
    zeroed = [" ".join([*row.split()[:3], "0"]) for row in data[::300]]
    (tmp_path / "zero.alta").write_text("\n".join(head + zeroed) + "\n")
    assert main(["import", str(tmp_path / "zero.alta"), "--out", str(tmp_path / "ds")]) == 0
    out = tmp_path / "road.json"
    fit = tmp_path / "fit.json"          # what `rig fit` gives there: kd 0, its u undetermined (null)
    fit.write_text(json.dumps({"model": "lambert", "params": {"kd": 0.0}, "covariance": {"kd": {"kd": None}}}))
    argv = ["export", str(tmp_path / "ds"), "--format", "road", "--fit", str(fit), "--out", str(out)]
    assert main(argv) == 0, capsys.readouterr().err
    doc = _strict(out)
    assert doc["S1"] is None and "S1" in doc["undefined"]["quantities"] and doc["rig_version"]
