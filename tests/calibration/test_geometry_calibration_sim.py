"""`rig calibrate geometry` on the simulated rig, whose truths are known: axis zero errors of σ 0.3° (30× the
default), a camera mount and a holder tilt. The board views and the lamp views are rendered through the sensor
model at a third of the LMK's resolution (same field of view) to keep the run short."""

import numpy as np
import pytest
import yaml

from rig.calibration.geometry import GeometryCalibrationError, measure
from rig.cli.main import main
from rig.config.geometry_calibration import load_geometry_calibration
from rig.config.rigfile import load_rig_config, simulated_rig
from rig.physics.charuco_board import BoardLayout
from rig.physics.geometry import AXIS_NAMES
from rig.physics.goniometer_fit import calibration_poses
from rig.simulators.rig import SimulatedRig

#: The LMK 98-4's sensor binned 3×3: the same field of view, 464×348 pixels.
SMALL_CAMERA = {"width_px": 464, "height_px": 348, "pixel_pitch_um": 19.35}
TRUTHS = {"axis_zero_sigma_deg": 0.3, "camera_mount_sigma_deg": 0.2, "holder_tilt_sigma_deg": 0.1, "seed": 7}


def write_rig(folder, **extra):
    path = folder / "rig.yaml"
    path.write_text(yaml.safe_dump({"name": "geometry test", "camera": SMALL_CAMERA, "simulation": TRUTHS, **extra}))
    return path


def truth(rig_path):
    """The simulated rig's truths, as the run drew them (the same seed, the same order)."""
    world = SimulatedRig(load_rig_config(rig_path), "lambert", {"kd": 0.5}).world
    return np.array([world.axis_zero_deg[name] for name in AXIS_NAMES]), world.holder_tilt_deg, world.camera_mount_deg


def test_calibrate_geometry_recovers_every_axis_zero_within_001_deg_and_its_u_covers_the_truth(tmp_path, capsys):
    rig = write_rig(tmp_path)
    out = tmp_path / "geometry.yaml"
    assert main(["calibrate", "geometry", "--rig", str(rig), "--out", str(out)]) == 0
    assert "written" in capsys.readouterr().out
    cal = load_geometry_calibration(out)
    zeros, tilt, mount = truth(rig)
    found, u = np.array(cal.zero_offsets_deg()), np.array(cal.zero_u_deg())
    assert np.max(np.abs(zeros)) > 0.2                                  # errors worth finding
    assert np.all(np.abs(found - zeros) < 0.01), found - zeros
    assert np.all(np.abs(found - zeros) <= 2 * u), (found - zeros) / u  # k = 2
    for name, value in (("tilt_x_deg", tilt[0]), ("tilt_y_deg", tilt[1]), ("roll_deg", mount[2])):
        estimate = cal.parameters[name]
        assert abs(estimate.value - value) <= 3 * estimate.u, name
    # the camera's pointing: turned about the sensor's y axis it looks past the centre along the image's columns;
    # the principal point stands for a turn on the mount to second order (its u does not hold that)
    for estimate, value in ((cal.pointing_x_deg, mount[1]), (cal.pointing_y_deg, mount[0])):
        assert abs(estimate.value - value) < 0.002, (estimate, value)
    assert not [v for v in cal.fit.views if v.rejected]

    # the rig file names it: the offsets reach the rig, and angle_u_deg comes from their uncertainty
    with_cal = tmp_path / "calibrated.yaml"
    with_cal.write_text(yaml.safe_dump({"camera": SMALL_CAMERA, "simulation": TRUTHS,
                                        "geometry": {"calibration_file": out.name, "angle_u_deg": 0.5}}))
    config = load_rig_config(with_cal)
    assert config.geometry.calibration is not None
    assert config.geometry.calibration.zero_offsets_deg == pytest.approx(tuple(found))
    assert config.geometry.calibration.date == cal.date
    assert config.geometry.angle_u_deg == pytest.approx(np.hypot(u.max(), config.geometry.readback_u_deg))


def test_a_board_the_camera_does_not_see_is_one_message_and_nothing_is_written(tmp_path):
    """The operator forgot to mount the board: the camera sees the empty holder."""
    config = load_rig_config(write_rig(tmp_path))
    boards, lamps = calibration_poses(6, 2)
    with SimulatedRig(config, "lambert", {"kd": 0.5}) as sim:
        camera = sim.devices.camera
        with pytest.raises(GeometryCalibrationError, match="the board was not found in any of the 6 views"):
            measure(sim.devices, config, BoardLayout(), board_poses=boards, lamp_poses=lamps,
                    show=lambda scene: camera.show("open" if scene.startswith("board") else scene))
        assert not sim.devices.lamp.output_is_on()


def test_a_degenerate_pose_set_is_one_message_and_nothing_is_written(tmp_path, monkeypatch, capsys):
    """Views that never turn the stage: its zero cannot be told from the holder's tilt."""
    rig = write_rig(tmp_path)
    out = tmp_path / "geometry.yaml"
    boards, lamps = calibration_poses(6, 2)
    same = [(0.0, 0.0, -90.0 + side, 70.0) for side in (-40.0, -20.0, 0.0, 20.0, 40.0, 10.0)]
    monkeypatch.setattr("rig.cli.calibrate_geometry.calibration_poses", lambda views, lamp_views: (same, lamps))
    assert main(["calibrate", "geometry", "--rig", str(rig), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "degenerate pose set" in err and "nothing written" in err
    assert not out.exists()


@pytest.mark.parametrize(("extra", "message"), [
    (["--views", "5"], "at least 6 board views"),
    (["--board", "missing.yaml"], "missing.yaml"),
])
def test_bad_arguments_are_refused_before_anything_moves(tmp_path, capsys, extra, message):
    out = tmp_path / "geometry.yaml"
    assert main(["calibrate", "geometry", "--rig", str(write_rig(tmp_path)), "--out", str(out), *extra]) == 2
    assert message in capsys.readouterr().err
    assert not out.exists()


def test_a_rig_file_naming_a_bad_calibration_file_is_refused_at_load(tmp_path):
    (tmp_path / "geometry.yaml").write_text("format: rig-geometry-calibration\nversion: 1\n")
    path = write_rig(tmp_path, geometry={"calibration_file": "geometry.yaml"})
    with pytest.raises(Exception, match="key 'geometry.calibration_file'"):
        load_rig_config(path)


def test_a_typed_calibration_without_its_file_is_refused(tmp_path):
    summary = {"file": "g.yaml", "date": "2026-11-27", "zero_offsets_deg": [0.1, 0, 0, 0], "zero_u_deg": [0, 0, 0, 0]}
    with pytest.raises(Exception, match="calibration is written by rig from calibration_file"):
        load_rig_config(write_rig(tmp_path, geometry={"calibration": summary}))


def test_the_board_is_seen_through_the_clearest_filter_of_the_wheel(tmp_path):
    """A wheel left on its densest filter (by a glossy campaign) is turned to the open position first."""
    config = simulated_rig()

    class Stop(Exception):
        pass

    def stop(scene):
        raise Stop

    with SimulatedRig(config, "lambert", {"kd": 0.5}) as sim:
        sim.devices.attenuator.move_to(6)
        with pytest.raises(Stop):
            measure(sim.devices, config, BoardLayout(), board_poses=[], lamp_poses=[], show=stop)
        assert sim.devices.attenuator.position() == 1


def test_a_lamp_the_supply_keeps_off_is_named_in_each_lamp_view(tmp_path):
    """The interlock opens as the lamp views begin: each view's line says why the exit is dark, as the supply tells
    it (a served rig too fast for its client's computing gets its communication watchdog's reason the same way)."""
    config = load_rig_config(write_rig(tmp_path))
    boards, lamps = calibration_poses(6, 2)
    lines: list[str] = []
    with SimulatedRig(config, "lambert", {"kd": 0.5}) as sim:
        camera = sim.devices.camera

        def show(scene):
            if scene == "open":
                sim.peers["lamp"].set_interlock(True)
            camera.show(scene)

        with pytest.raises(GeometryCalibrationError, match="0 lamp views left"):
            measure(sim.devices, config, BoardLayout(), board_poses=boards, lamp_poses=lamps, show=show,
                    progress=lines.append)
        assert not sim.devices.lamp.output_is_on()
    lamp_lines = [line for line in lines if line.startswith("lamp-")]
    assert len(lamp_lines) == 2
    assert all("lamp exit not found: the lamp is off: " in line and "interlock" in line for line in lamp_lines)


def test_a_lamp_its_supply_switched_off_after_a_stall_is_switched_on_again_and_the_view_taken_once_more(tmp_path):
    """The computer stalls past the supply's communication watchdog after the first lamp view (as a served rig's
    client does when the rig runs many times faster than its computing): the next view finds the exit dark, the
    supply says its watchdog switched the output off, the lamp goes on again and the view counts."""
    config = load_rig_config(write_rig(tmp_path))
    boards, lamps = calibration_poses(6, 2)
    lines: list[str] = []
    with SimulatedRig(config, "lambert", {"kd": 0.5}) as sim:
        def stall_after_the_first_lamp_view(line: str) -> None:
            lines.append(line)
            if line.startswith("lamp-01"):
                sim.world.clock.advance(2 * config.lamp.watchdog_s)      # no command meanwhile: no feed
                assert sim.peers["lamp"].check_watchdog() is not None

        measure(sim.devices, config, BoardLayout(), board_poses=boards, lamp_poses=lamps, show=sim.devices.camera.show,
                progress=stall_after_the_first_lamp_view)
        assert not sim.devices.lamp.output_is_on()
    relit = [line for line in lines if "switched on again" in line]
    assert len(relit) == 1 and "the supply's communication watchdog switched the output off" in relit[0]
    assert [line.split(":")[0] for line in lines if line.startswith("lamp-") and "lamp exit at" in line] == [
        "lamp-01", "lamp-02"]
