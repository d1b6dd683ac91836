"""The simulated rig with Zaber peers for all four axes, chosen only by the rig file's driver names: a
campaign runs over the Zaber ASCII protocol end to end (real driver, peer on loopback)."""

from __future__ import annotations

import csv
import json

from repo_paths import RIGS, TEST_CAMPAIGNS
from rig.cli.main import main
from rig.config.rigfile import load_rig_config


def test_a_campaign_runs_on_zaber_stages_chosen_by_the_rig_file(tmp_path):
    zaber, modbus = load_rig_config(RIGS / "simulated-zaber.yaml"), load_rig_config(RIGS / "simulated.yaml")
    assert zaber.devices.lamp == modbus.devices.lamp and zaber.axes == modbus.axes      # only the driver differs
    out = tmp_path / "ds"
    assert main(["run", str(TEST_CAMPAIGNS / "served.yaml"), "--rig", str(RIGS / "simulated-zaber.yaml"),
                 "--out", str(out), "--quiet"]) == 0
    manifest = json.loads((out / "dataset.json").read_text())
    assert manifest["status"] == "complete" and manifest["counts"]["measured"] == 16
    with (out / "brdf.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 16
    identities = manifest["rig"]["identities"]
    assert identities["arm"].count("Zaber") == 2 and identities["stage"].count("Zaber") == 2
