"""`rig calibrate camera` on the simulated camera, whose truths are known: the recovered coefficient, PRNU,
fall-off and linearity error lie within k = 2 of their stated uncertainties, a nonlinear camera is caught,
and a campaign measured with the calibration file gives the same luminances with its u_rel_calibration."""

import numpy as np
import pytest
import yaml

from repo_paths import TEST_CAMPAIGNS
from rig.acquisition.run import run_campaign
from rig.calibration.radiometric import measure
from rig.cli.main import main
from rig.config.camera_calibration import load_camera_calibration
from rig.config.campaign import load_campaign
from rig.config.rigfile import load_rig_config
from rig.core.values import Window
from rig.data.dataset_reader import load
from rig.physics import camera_calibration as cc
from rig.physics.brdf_models import get_model
from rig.session.connect import open_campaign_rig
from rig.simulators.camera import UniformSourceCamera
from rig.simulators.sensor import convert_nonlinear
from rig.simulators.world import SimWorld

REFERENCE_CD_M2 = 100.0
#: A machine-vision sensor with a short lens (visible fall-off) and a strong DSNU to find.
CAMERA = {"width_px": 160, "height_px": 120, "focal_length_mm": 8.0}


def write_rig(folder, camera=CAMERA, **simulation):
    path = folder / "rig.yaml"
    path.write_text(yaml.safe_dump({"name": "calibration test", "camera": dict(camera),
                                    "simulation": {"seed": 5, "dsnu_e_s": 100.0, **simulation}}))
    return path


def calibrate(folder, rig, *extra, u_ref=0.002):
    out = folder / "cal.yaml"
    code = main(["calibrate", "camera", "--rig", str(rig), "--reference-cd-m2", str(REFERENCE_CD_M2),
                 "--reference-u-rel", str(u_ref), "--out", str(out), *extra])
    assert code == 0
    return out


def truth_camera(rig):
    """The same simulated camera the command built (same seed, same draws): its truths."""
    config = load_rig_config(rig)
    return config, UniformSourceCamera(SimWorld(config, get_model("lambert"), {"kd": 0.5}), REFERENCE_CD_M2)


@pytest.fixture(scope="module")
def linear(tmp_path_factory):
    folder = tmp_path_factory.mktemp("linear")
    rig = write_rig(folder)
    out = calibrate(folder, rig)
    return (*load_camera_calibration(out), *truth_camera(rig))


def test_coefficient_recovered_within_its_measurement_uncertainty(linear):
    cal, flat, config, cam = linear
    centre = cal.centre
    rows, cols = cam.full_window().inner(centre)
    response = (cam.model.gain * cam.model.illumination)[rows, cols].mean()
    k_true = 1.0 / (config.camera.responsivity_e_per_cd_m2_s * config.camera.gain_dn_per_e * response)
    k = cal.coefficient
    u_measurement = np.sqrt(k.u_rel ** 2 - k.budget["reference"] ** 2)
    assert abs(k.cd_m2_per_dn_s / k_true - 1) <= 2 * u_measurement
    assert k.u_rel == pytest.approx(np.hypot(0.002, u_measurement))
    # the nominal 1/(responsivity·K) differs only by the centre's mean fall-off and PRNU
    assert k.cd_m2_per_dn_s * config.camera.responsivity_e_per_cd_m2_s * config.camera.gain_dn_per_e == \
        pytest.approx(1.0, abs=3e-3)


def test_prnu_and_falloff_recovered(linear):
    cal, flat, config, cam = linear
    f = cal.flat_field
    gain = cam.model.gain
    assert abs(f.prnu_rel - gain.std() / gain.mean()) <= 2 * f.u_prnu_rel
    # the fall-off polynomial at the sensor's corners, against cos⁴ there, relative to the centre
    c = config.camera
    r2 = ((c.width_px / 2) ** 2 + (c.height_px / 2) ** 2) * (c.pixel_pitch_um * 1e-3) ** 2
    corner = (c.focal_length_mm ** 2 / (c.focal_length_mm ** 2 + r2)) ** 2
    rows, cols = cam.full_window().inner(cal.centre)
    corner_true = corner * gain.mean() / (gain * cam.model.illumination)[rows, cols].mean()
    assert corner_true < 0.99                                   # a fall-off worth finding
    assert abs(f.falloff_corner_rel - corner_true) <= 2 * f.u_falloff_corner_rel
    # the flat field is the true relative response, to within its temporal noise
    truth = gain * cam.model.illumination
    truth = truth / truth[rows, cols].mean()
    assert np.std(flat / truth - 1) < 2 * 0.002


def test_linear_camera_le_within_noise_and_dark_gain_noise_recovered(linear):
    cal, flat, config, cam = linear
    assert cal.linearity.le_percent <= 2 * cal.linearity.u_le_percent
    ptc = cal.photon_transfer
    assert abs(ptc.gain_dn_per_e - config.camera.gain_dn_per_e) <= 2 * ptc.u_gain_dn_per_e + 2e-3 * ptc.gain_dn_per_e
    assert ptc.read_noise_e == pytest.approx(config.camera.read_noise_e, rel=0.03)
    longest = cal.dark[-1]
    dsnu_true = config.camera.gain_dn_per_e * cam.model.dark_e_s.std() * longest.exposure_s
    assert longest.dsnu_dn == pytest.approx(dsnu_true, rel=0.1)


def test_nonlinear_camera_detected(tmp_path):
    rig = write_rig(tmp_path, nonlinearity_rel=0.02)
    cal, _ = load_camera_calibration(calibrate(tmp_path, rig))
    config, cam = truth_camera(rig)
    lin = cal.linearity
    # the truth: the noise-free mean signal through the same fit
    full, fw = cam.full_window(), config.camera.full_well_e
    model = cam.model
    signal = [config.camera.gain_dn_per_e * np.mean(
        convert_nonlinear(model.mean_electrons(REFERENCE_CD_M2, t, full), model.nonlinearity_rel, fw)
        - convert_nonlinear(model.dark_e_s * t, model.nonlinearity_rel, fw)) for t in lin.exposures_s]
    used = np.array([d is not None for d in lin.deviation_percent])
    top = max(np.array(signal)[used]) / cc.LINEAR_RANGE[1]
    truth = cc.linearity(np.array(lin.exposures_s)[used], np.array(signal)[used], np.ones(used.sum()), top)
    assert truth.used.all()
    assert lin.le_percent > 10 * lin.u_le_percent                 # detected
    assert abs(lin.le_percent - truth.le_percent) <= 2 * lin.u_le_percent
    assert cal.coefficient.budget["linearity"] > 1e-3            # rates differ between exposures: in the budget


def test_campaign_with_the_calibration_file(tmp_path):
    """Same luminances within uncertainty, and u_rel_calibration is the file's."""
    camera = {"width_px": 160, "height_px": 120}        # the 50 mm lens: the ROI sees the lit spot
    rig = write_rig(tmp_path, camera)
    cal_path = calibrate(tmp_path, rig, "--frames", "4", u_ref=0.01)
    cal, _ = load_camera_calibration(cal_path)
    calibrated = tmp_path / "calibrated.yaml"
    calibrated.write_text(yaml.safe_dump({**yaml.safe_load(rig.read_text()),
                                          "camera": {**camera, "calibration_file": cal_path.name}}))
    campaign = load_campaign(TEST_CAMPAIGNS / "served.yaml")
    results = {}
    for name, path in (("plain", rig), ("calibrated", calibrated)):
        config = load_rig_config(path)
        out = tmp_path / name
        outcome = run_campaign(campaign, config, out, open_campaign_rig)
        assert outcome.status == "complete"
        results[name] = load(out)
    plain, calib = results["plain"], results["calibrated"]
    np.testing.assert_allclose(calib["u_rel_calibration"], cal.coefficient.u_rel, rtol=1e-12)
    np.testing.assert_allclose(plain["u_rel_calibration"], 0.0)
    # the same raw frames (same seed), reduced through the file's k and flat field instead of 1/(resp·K)
    diff = calib["luminance_cd_m2"] / plain["luminance_cd_m2"] - 1
    assert np.all(np.abs(diff) <= 2 * cal.coefficient.u_rel)
    assert np.all(np.abs(diff) < 3e-3)


def test_failures_give_one_clear_message(tmp_path, capsys):
    rig = write_rig(tmp_path)
    out = calibrate(tmp_path, rig, "--frames", "2")
    args = ["calibrate", "camera", "--rig", str(rig), "--reference-cd-m2", "100", "--reference-u-rel", "0.01"]
    assert main([*args, "--out", str(out)]) == 2
    assert "exists already" in capsys.readouterr().err
    assert main([*args, "--out", str(tmp_path / "b.yaml"), "--exposures", "1", "2", "3"]) == 2
    assert "saturated flats" in capsys.readouterr().err
    assert main([*args, "--out", str(tmp_path / "c.yaml"), "--exposures", "1e-4", "2e-4", "3e-4"]) == 2
    assert "too-dark flats" in capsys.readouterr().err
    dark = ["calibrate", "camera", "--rig", str(rig), "--reference-cd-m2", "1e-4", "--reference-u-rel", "0.01"]
    assert main([*dark, "--out", str(tmp_path / "d.yaml")]) == 2
    assert "too-dark flats" in capsys.readouterr().err
    assert main([*args, "--out", str(tmp_path / "e.yaml"), "--window", "500", "10"]) == 2
    assert "--window" in capsys.readouterr().err
    assert not list(tmp_path.glob("[bcde].*"))


def test_centre_window_is_where_the_flat_field_is_one(linear):
    cal, flat, _, _ = linear
    rows, cols = Window(0, 0, 160, 120).inner(cal.centre)
    assert flat[rows, cols].mean() == pytest.approx(1.0, abs=1e-6)


def test_operator_prompts_without_a_shutter(tmp_path):
    """A camera without a shutter (GenICam): the operator is asked to place the source, then to cap the
    lens, and the darks are ordinary frames; here the prompt switches the simulated source off."""
    rig = write_rig(tmp_path)
    _, cam = truth_camera(rig)
    asked = []

    def operator(text):
        asked.append(text)
        if "Cover the lens" in text:
            cam.source_cd_m2 = 0.0

    cal, flat = measure(cam, reference_cd_m2=REFERENCE_CD_M2, reference_u_rel=0.01, exposures_s=None, frames=2,
                        centre_px=(40, 40), prompt=operator, shutter=False, flat_file="x.flat.npy")
    assert [a.split()[0] for a in asked] == ["Place", "Cover"]
    assert cal.dark[0].mean_dn == pytest.approx(64, abs=1)              # dark frames, not lit ones
    assert cal.flat_field.file == "x.flat.npy" and flat.shape == (120, 160)
