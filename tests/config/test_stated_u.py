"""A rig file that states no calibration u says so (issue 34): never a silent 0."""

import yaml

from repo_paths import ROOT
from rig.config.rigfile import RigConfig, load_rig_config, simulated_rig

EXAMPLE = ROOT / "campaigns" / "rigs" / "example-lab.yaml"


def test_example_lab_rig_states_its_calibrations():
    rig = load_rig_config(EXAMPLE)
    assert rig.uncertainty_not_stated == ()
    assert 0.01 <= rig.camera.calibration_u_rel <= 0.03 and 0.01 <= rig.meter.calibration_u_rel <= 0.03


def test_simulated_rig_states_the_simulators_truth():
    assert simulated_rig().uncertainty_not_stated == ()
    assert load_rig_config(ROOT / "campaigns" / "rigs" / "simulated.yaml").uncertainty_not_stated == ()


def test_unstated_calibrations_are_recorded_and_survive_the_manifest():
    data = yaml.safe_load(EXAMPLE.read_text())
    del data["camera"]["calibration_u_rel"], data["meter"]["calibration_u_rel"]
    data["devices"]["attenuator"] = {"driver": "fw102c", "address": "/dev/ttyUSB2"}
    data["attenuator"] = {"filters": [{"position": 1, "transmission": 1.0}, {"position": 2, "transmission": 0.1},
                                      {"position": 3, "transmission": 0.01, "u_rel": 0.01}]}
    rig = RigConfig.model_validate(data)
    assert rig.uncertainty_not_stated == ("camera.calibration_u_rel", "meter.calibration_u_rel",
                                          "attenuator.filters[position 2].u_rel")
    assert rig.camera.calibration_u_rel == 0.0                     # used as 0 ...
    again = RigConfig.model_validate(rig.model_dump(mode="json"))  # ... and said so after a round trip
    assert again.uncertainty_not_stated == rig.uncertainty_not_stated
