"""Camera calibration files: written and read back, referenced from a rig file, and refused clearly when
malformed, incomplete or made for another sensor."""

import shutil

import numpy as np
import pytest
import yaml

from rig.cli.main import main
from rig.config.camera_calibration import (
    CameraCalibrationError,
    load_camera_calibration,
    save_camera_calibration,
)
from rig.config.rigfile import RigConfigError, load_rig_config
from rig.physics.camera_calibration import CalibratedSensorInfo

CAMERA = {"width_px": 64, "height_px": 48, "focal_length_mm": 8.0}


@pytest.fixture(scope="module")
def made(tmp_path_factory):
    """A calibration file of a small simulated camera, as `rig calibrate camera` writes it."""
    folder = tmp_path_factory.mktemp("made")
    rig = folder / "rig.yaml"
    rig.write_text(yaml.safe_dump({"camera": CAMERA}))
    out = folder / "cam.yaml"
    assert main(["calibrate", "camera", "--rig", str(rig), "--reference-cd-m2", "50", "--reference-u-rel", "0.01",
                 "--out", str(out), "--frames", "2", "--window", "16", "16"]) == 0
    return out


def copy(made, folder, change=None, flat=None):
    """The made calibration in `folder`, its YAML changed by `change(data)` and its flat replaced by `flat`."""
    shutil.copy(made.with_suffix(".flat.npy"), folder / "cam.flat.npy")
    data = yaml.safe_load(made.read_text())
    if change:
        change(data)
    path = folder / "cam.yaml"
    path.write_text(yaml.safe_dump(data))
    if flat is not None:
        np.save(folder / "cam.flat.npy", flat)
    return path


def test_written_file_reads_back(made):
    cal, flat = load_camera_calibration(made)
    assert cal.camera.width_px == 64 and flat.shape == (48, 64) and flat.dtype == np.float32
    assert cal.reference.luminance_cd_m2 == 50 and cal.reference.u_rel == 0.01
    assert cal.flat_field.file == "cam.flat.npy"
    assert "EMVA 1288" in cal.method
    assert cal.coefficient.u_rel >= 0.01
    text = made.read_text()
    assert text.startswith("# Radiometric calibration") and "dsnu_dn" in text and "le_percent" in text


def test_save_refuses_to_overwrite(made, tmp_path):
    cal, flat = load_camera_calibration(made)
    with pytest.raises(CameraCalibrationError, match="exists already"):
        save_camera_calibration(made, cal, flat)


def test_rig_file_references_it_relative_to_itself(made, tmp_path):
    folder = tmp_path / "lab"
    folder.mkdir()
    path = copy(made, folder)
    rig = tmp_path / "rig.yaml"
    rig.write_text(yaml.safe_dump({"camera": {**CAMERA, "calibration_file": "lab/cam.yaml"}}))
    config = load_rig_config(rig)
    sensor = config.camera.sensor_info()
    cal, flat = load_camera_calibration(path)
    assert isinstance(sensor, CalibratedSensorInfo)
    assert sensor.calibration_cd_m2_per_dn_s == cal.coefficient.cd_m2_per_dn_s
    assert sensor.calibration_u_rel == cal.coefficient.u_rel          # replaces camera.calibration_u_rel
    np.testing.assert_array_equal(sensor.flat_field, flat)


def test_calibration_for_another_sensor_is_refused(made, tmp_path):
    copy(made, tmp_path)
    rig = tmp_path / "rig.yaml"
    rig.write_text(yaml.safe_dump({"camera": {**CAMERA, "width_px": 80, "calibration_file": "cam.yaml"}}))
    with pytest.raises(RigConfigError, match=r"camera.calibration_file.*made for a 64×48 sensor.*80×48"):
        load_rig_config(rig)


def test_missing_calibration_file_named(tmp_path):
    rig = tmp_path / "rig.yaml"
    rig.write_text(yaml.safe_dump({"camera": {**CAMERA, "calibration_file": "nowhere.yaml"}}))
    with pytest.raises(RigConfigError, match=r"rig.yaml: key 'camera.calibration_file'.*nowhere.yaml: camera "
                                             r"calibration file not found"):
        load_rig_config(rig)


def _set(path, value):
    def change(data):
        *parents, last = path.split(".")
        for p in parents:
            data = data[p]
        if value is None:
            del data[last]
        else:
            data[last] = value
    return change


@pytest.mark.parametrize("path, value, message", [
    ("coefficient.cd_m2_per_dn_s", -1.0, r"coefficient.cd_m2_per_dn_s.*greater than 0"),
    ("coefficient.u_rel", 0.5, r"coefficient.*not the root sum of squares"),
    ("reference", None, r"missing key 'reference'"),
    ("format", "something else", r"format.*rig-camera-calibration"),
    ("flat_field.falloff_coefficients", [1.0, 0.0], r"flat_field.*has 15 coefficients"),
    ("linearity.signal_dn", [1.0], r"linearity.*same length"),
    ("coefficient.centre_window", [60, 0, 16, 16], r"centre_window.*not inside the 64×48 sensor"),
    ("flat_field.prnu_rel", float("nan"), r"flat_field.prnu_rel"),
    ("dark", [], r"dark.*at least 1"),
    ("extra_key", 1, r"extra_key"),
])
def test_malformed_yaml_refused_naming_file_and_key(made, tmp_path, path, value, message):
    bad = copy(made, tmp_path, _set(path, value))
    with pytest.raises(CameraCalibrationError, match=message) as err:
        load_camera_calibration(bad)
    assert str(bad) in str(err.value)


@pytest.mark.parametrize("flat, message", [
    (np.ones((48, 63)), r"shape \(48, 63\).*64×48"),
    (np.ones((48, 64), dtype=np.int32), "int32"),
    (np.full((48, 64), np.nan), "finite and positive"),
    (np.zeros((48, 64)), "finite and positive"),
])
def test_bad_flat_field_refused(made, tmp_path, flat, message):
    bad = copy(made, tmp_path, flat=flat)
    with pytest.raises(CameraCalibrationError, match=rf"key 'flat_field.file'.*cam.flat.npy.*{message}"):
        load_camera_calibration(bad)


def test_missing_or_unreadable_flat_field(made, tmp_path):
    bad = copy(made, tmp_path)
    (tmp_path / "cam.flat.npy").write_bytes(b"not numpy")
    with pytest.raises(CameraCalibrationError, match="not a numpy .npy array"):
        load_camera_calibration(bad)
    (tmp_path / "cam.flat.npy").unlink()
    with pytest.raises(CameraCalibrationError, match="cam.flat.npy: file not found"):
        load_camera_calibration(bad)


def test_not_a_mapping(tmp_path):
    bad = tmp_path / "cam.yaml"
    bad.write_text("- 1\n- 2\n")
    with pytest.raises(CameraCalibrationError, match="must be a YAML mapping"):
        load_camera_calibration(bad)
