"""`rig devices --check RIG.yaml` (issue 29 item 8): the rig file, its drive maps and calibration file, and every
device's driver checked without opening any port or connection; exit 0 and what was checked, or exit 2 and one
message naming the key and the file.

campaigns/rigs/example-lab.yaml names LAN addresses and serial ports: every way of opening one fails the test.
"""

import shutil
import socket
from pathlib import Path

import pytest
import serial
import yaml

from repo_paths import ROOT
from rig.cli.main import main

LAB = ROOT / "campaigns" / "rigs" / "example-lab.yaml"
DRIVE_MAP = ROOT / "drivers" / "drive_maps" / "oriental-az.yaml"


@pytest.fixture(autouse=True)
def nothing_opens(monkeypatch):
    """Any socket connection or serial port opened during a test fails it."""
    def refuse(*args, **kwargs):
        raise AssertionError(f"`rig devices --check` opened a connection: {args[1:] or kwargs}")
    monkeypatch.setattr(socket.socket, "connect", refuse)
    monkeypatch.setattr(socket.socket, "connect_ex", refuse)
    monkeypatch.setattr(socket, "create_connection", refuse)
    monkeypatch.setattr(serial.Serial, "open", refuse)
    monkeypatch.setattr(serial, "serial_for_url", refuse)


def lab_copy(tmp_path: Path, change=None) -> Path:
    """example-lab.yaml in `tmp_path`, its data changed by `change(data)`."""
    data = yaml.safe_load(LAB.read_text())
    if change:
        change(data)
    path = tmp_path / "lab.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_the_example_lab_rig_is_checked_without_connecting(capsys):
    assert main(["devices", "--check", str(LAB)]) == 0
    out = capsys.readouterr().out
    assert out.startswith(f"{LAB}: rig example-lab (hardware), valid")
    for line in ("arm        driver modbus-drive → rig.drivers.modbus_drive.ModbusDriveLink; "
                 "address modbus-tcp://192.168.10.21:502; map oriental-az",
                 "lamp       driver delta-sm → rig.drivers.delta_sm.DeltaSM; address socket://192.168.10.30:8462",
                 "meter      driver p9710 → rig.drivers.p9710.P9710; address /dev/ttyUSB1",
                 "camera     driver lmk → rig.drivers.lmk.LmkCamera; camera dxm2134; lens oC202517f25"):
        assert line in out, out
    assert out.rstrip().endswith("nothing was opened or connected")


def test_a_drive_map_file_next_to_the_rig_file_is_read(tmp_path, capsys):
    shutil.copy(DRIVE_MAP, tmp_path / "az.yaml")
    rig = lab_copy(tmp_path, lambda d: d["devices"]["arm"].update(map="az.yaml"))
    assert main(["devices", "--check", str(rig)]) == 0
    assert f"map {tmp_path / 'az.yaml'}" in capsys.readouterr().out


def test_the_simulated_rig_file_is_checked(capsys):
    assert main(["devices", "--check", str(ROOT / "campaigns" / "rigs" / "simulated.yaml")]) == 0
    assert "rig simulated (simulated), valid" in capsys.readouterr().out


def _set(section: str, entry: str, **values):
    return lambda data: data[section][entry].update(values)


BROKEN = {
    "driver not installed": (_set("devices", "lamp", driver="no-such-supply"),
                             "key 'devices.lamp.driver': no lamp driver named 'no-such-supply' is installed"),
    "driver of another role": (_set("devices", "meter", driver="delta-sm"),
                               "key 'devices.meter.driver': driver 'delta-sm'"),
    "option the driver does not take": (lambda d: d["devices"].update(arm={"driver": "zaber", "address": "/dev/ttyUSB3",
                                                                           "device_ids": [1, 2]}),
                                        "key 'devices.arm.driver': driver 'zaber' does not take the options"),
    "camera class that does not import": (lambda d: d["devices"].update(camera={"driver": "python:no_such_mod:Cam"}),
                                          "cannot load camera driver 'python:no_such_mod:Cam'"),
    "address auto on hardware": (_set("devices", "meter", address="auto"), "key 'devices.meter.address'"),
    "address syntax": (_set("devices", "lamp", address="socket://192.168.10.30"), "devices.lamp.address"),
    "missing drive map file": (_set("devices", "stage", map="maps/az.yaml"), "key 'devices.stage.map'"),
    "missing calibration file": (lambda d: d["camera"].update(calibration_file="cam.yaml"),
                                 "key 'camera.calibration_file'"),
    "calibration file for a calibrated camera": (lambda d: d["camera"].update(calibration_file="lab.yaml"),
                                                 "key 'camera.calibration_file'"),
    "unknown key": (lambda d: d["lamp"].update(voltage=12), "lamp.voltage"),
}


@pytest.mark.parametrize("name", sorted(BROKEN))
def test_a_broken_rig_file_is_one_message_naming_the_key_and_the_file(tmp_path, capsys, name):
    change, message = BROKEN[name]
    rig = lab_copy(tmp_path, change)
    assert main(["devices", "--check", str(rig)]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    err = captured.err
    assert err.startswith(f"rig: error: {rig}") and message in err and err.count("rig: error") == 1, err


def test_check_needs_a_rig_file_and_is_not_list(capsys):
    assert main(["devices", "--check"]) == 2
    assert main(["devices", "--list", "--check", str(LAB)]) == 2
    assert capsys.readouterr().err.count("rig: error: ") == 2
