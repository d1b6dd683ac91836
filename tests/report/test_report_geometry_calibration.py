"""`rig report`'s calibrations table shows the geometry calibration the run used (docs/geometry-calibration.md):
its file, its date and the axes' zero offsets, from the manifest's rig configuration."""

from rig.config.geometry_calibration import GeometryCalibrationSummary
from rig.config.rigfile import simulated_rig
from rig.report.content import _calibrations


def _manifest(rig):
    return {"rig": {"config": rig.model_dump(mode="json")}}


def test_the_geometry_calibration_and_its_date_are_shown():
    rig = simulated_rig()
    summary = GeometryCalibrationSummary(file="lab/geometry.yaml", date="2026-11-27T23:00:00+00:00",
                                         zero_offsets_deg=(0.12, -0.3, 0.05, 0.2), zero_u_deg=(0.002,) * 4)
    rig = rig.model_copy(update={"geometry": rig.geometry.model_copy(update={"calibration": summary})})
    rows = dict(_calibrations(_manifest(rig)))
    assert rows["Geometry calibration"] == "lab/geometry.yaml of 2026-11-27T23:00:00+00:00"
    assert rows["Axis zero offsets"] == "0.12° / -0.3° / 0.05° / 0.2°"


def test_a_run_without_one_says_so():
    assert dict(_calibrations(_manifest(simulated_rig())))["Geometry calibration"] == "none (nominal axis zeros)"
