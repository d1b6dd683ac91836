"""No silent zero (issue 34): a calibration u the rig file does not state is named where the budget is shown."""

import json

from rig.data.dataset_writer import DatasetWriter
from rig.physics.budget import BUDGET_COLUMNS, NOT_STATED, campaign_budget, mark_not_stated, not_stated
from rig.report.content import _calibrations

KEYS = ["camera.calibration_u_rel", "attenuator.filters[position 2].u_rel"]
MANIFEST = {"rig": {"name": "lab", "simulated": False, "config": {"uncertainty_not_stated": KEYS,
                                                                   "camera": {"calibration_u_rel": 0.0},
                                                                   "meter": {"calibration_u_rel": 0.015}}}}


def table() -> list[dict]:
    row = dict.fromkeys(BUDGET_COLUMNS, 0.001)
    return campaign_budget([row, row], BUDGET_COLUMNS)


def test_the_budget_names_each_unstated_calibration_and_nothing_else():
    marked = {b["component"]: b["meaning"] for b in mark_not_stated(table(), not_stated(MANIFEST))}
    assert marked["u_rel_calibration"].endswith(f"{NOT_STATED} (camera.calibration_u_rel)")
    assert marked["u_rel_attenuation"].endswith(f"{NOT_STATED} (attenuator.filters[position 2].u_rel)")
    assert NOT_STATED not in marked["u_rel_meter_calibration"]
    assert mark_not_stated(table(), not_stated({})) == table()


def test_dataset_json_and_the_report_say_so(tmp_path):
    writer = DatasetWriter(tmp_path / "out", MANIFEST)
    writer.update_manifest(uncertainty_budget=table())
    writer.close()
    budget = json.loads((tmp_path / "out" / "dataset.json").read_text())["uncertainty_budget"]
    assert sum(NOT_STATED in b["meaning"] for b in budget) == 2
    rows = dict(_calibrations(MANIFEST))
    assert rows["Camera calibration u (rel.)"] == NOT_STATED and rows["Meter calibration u (rel.)"] != NOT_STATED


def test_the_budget_says_which_components_are_shared():
    shared = {b["component"] for b in table() if b["correlated"]}
    assert shared == {"u_rel_calibration", "u_rel_meter_calibration", "u_rel_attenuation", "u_rel_angle_zero",
                      "u_rel_texture_static"}
