"""Rig files: the shipped ones load, the simulated one is the default, bad ones are refused clearly."""

from pathlib import Path

import pytest
import yaml

from drivers.factory import connect_devices, vendor_camera
from drivers.interfaces import DeviceError
from rig.cli import main
from rig.rigconfig import RigConfig, RigConfigError, load_rig_config
from simulators.clock import SimClock

RIGS = Path(__file__).resolve().parents[1] / "campaigns" / "rigs"


def test_simulated_rig_file_is_the_default():
    assert load_rig_config(RIGS / "simulated.yaml") == RigConfig()


def test_example_lab_rig_file_loads():
    cfg = load_rig_config(RIGS / "example-lab.yaml")
    assert not cfg.simulated
    assert cfg.devices.arm.address.startswith("modbus-tcp://")
    assert cfg.devices.stage.address.startswith("modbus-rtu://")
    assert cfg.devices.lamp.address.endswith(":8462")
    assert cfg.devices.camera.driver == "python:mylab.lmk:LmkCamera"


@pytest.mark.parametrize("change, key, rule", [
    ({"devices": {"lamp": {"driver": "keithley"}}}, "devices.lamp.driver", "'delta-sm'"),
    ({"devices": {"camera": {"driver": "lmk"}}}, "devices.camera", "python:package.module:Class"),
    ({"axes": {"arm_polar": {"limits_deg": [90, -90], "speed_deg_s": 1, "accel_deg_s2": 1}}},
     "axes.arm_polar", "low < high"),
    ({"geometry": {"camera_distance_m": -1}}, "geometry.camera_distance_m", "greater than 0"),
    ({"meter": {"calibration": 3}}, "meter.calibration", "allowed here: calibration_lx_per_a"),
])
def test_bad_rig_file(tmp_path, change, key, rule):
    f = tmp_path / "rig.yaml"
    f.write_text(yaml.safe_dump(change))
    with pytest.raises(RigConfigError) as err:
        load_rig_config(f)
    line = next(l for l in str(err.value).splitlines() if f"'{key}'" in l)
    assert rule in line


def test_auto_address_needs_the_simulated_rig():
    with pytest.raises(DeviceError, match="arm: address 'auto' only works on the simulated rig"):
        connect_devices(RigConfig(simulated=False), SimClock())


def test_unreachable_device_is_named(tmp_path):
    cfg = load_rig_config(RIGS / "example-lab.yaml")
    local = cfg.devices.model_copy(update={"arm": cfg.devices.arm.model_copy(
        update={"address": "modbus-tcp://127.0.0.1:9", "timeout_s": 0.2})})
    with pytest.raises(DeviceError, match="arm"):
        connect_devices(cfg.model_copy(update={"devices": local}), SimClock())


def test_vendor_camera_import_error_is_clear():
    cfg = load_rig_config(RIGS / "example-lab.yaml")
    with pytest.raises(DeviceError, match="cannot load camera driver 'python:mylab.lmk:LmkCamera'"):
        vendor_camera(cfg, cfg.devices.camera)


def test_rig_devices_prints_identities_and_moves_nothing(capsys):
    assert main(["devices", str(RIGS / "simulated.yaml")]) == 0
    out = capsys.readouterr().out
    for role in ("arm", "stage", "lamp", "meter", "camera"):
        assert f"\n{role}" in "\n" + out
    assert "DELTA ELEKTRONIKA" in out and "P9710" in out and "Modbus" in out
    assert "output off" in out


def test_rig_devices_bad_file(tmp_path, capsys):
    f = tmp_path / "r.yaml"
    f.write_text("devices: [1, 2]\n")
    assert main(["devices", str(f)]) == 2
    assert "invalid rig configuration" in capsys.readouterr().err


def test_run_with_rig_option(tmp_path):
    campaign = Path(__file__).parent / "campaigns" / "e2e-reduced.yaml"
    assert main(["plan", str(campaign), "--rig", str(RIGS / "simulated.yaml")]) == 0
