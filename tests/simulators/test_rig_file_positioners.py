"""The simulated rig's positioners are chosen only by the rig file: Zaber ASCII stages for all four axes
(simulated-zaber.yaml), or Oriental Motor AZ drives serving the AZ's published Modbus registers
(simulated.yaml, `driver: modbus-drive, map: oriental-az`). A campaign runs end to end on either, through
the real driver and a peer on loopback."""

from __future__ import annotations

import csv
import json

import pytest

from repo_paths import RIGS, TEST_CAMPAIGNS
from rig.cli.main import main
from rig.config.rigfile import load_rig_config


def test_only_the_positioner_entries_differ():
    zaber, modbus = load_rig_config(RIGS / "simulated-zaber.yaml"), load_rig_config(RIGS / "simulated.yaml")
    assert zaber.devices.lamp == modbus.devices.lamp and zaber.axes == modbus.axes
    assert (zaber.devices.arm.driver, modbus.devices.arm.driver, modbus.devices.arm.map) == \
        ("zaber", "modbus-drive", "oriental-az")


@pytest.mark.parametrize("rig_file, make", [("simulated-zaber.yaml", "Zaber"),
                                            ("simulated.yaml", "Oriental Motor AZ series drive, Modbus id")])
def test_a_campaign_runs_on_the_positioners_the_rig_file_names(tmp_path, rig_file, make):
    out = tmp_path / "ds"
    assert main(["run", str(TEST_CAMPAIGNS / "served.yaml"), "--rig", str(RIGS / rig_file),
                 "--out", str(out), "--quiet"]) == 0
    manifest = json.loads((out / "dataset.json").read_text())
    assert manifest["status"] == "complete" and manifest["counts"]["measured"] == 16
    with (out / "brdf.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 16
    identities = manifest["rig"]["identities"]
    assert identities["arm"].count(make) == 2 and identities["stage"].count(make) == 2
