"""The simulated camera's scenes for `rig calibrate geometry` (docs/sim-camera-protocol.md, `SCENE`): the ChArUco
board on the holder, rendered where the pinhole model puts it, and the lamp's exit; switched in-process and over
the served camera's protocol."""

import cv2
import numpy as np
import pytest
from sim_worlds import lit_world

from rig.config.rigfile import RigConfig
from rig.core.errors import DeviceError
from rig.core.values import Window
from rig.drivers.sim_camera import ServedCamera
from rig.physics import goniometer_fit as gf
from rig.physics.brdf_models import get_model
from rig.physics.charuco_board import BoardLayout
from rig.physics.geometry import AXIS_NAMES
from rig.simulators.board import lamp_exit_luminance
from rig.simulators.camera import SimCamera
from rig.simulators.camera_server import CameraServer
from rig.simulators.clock import SimClock
from rig.simulators.world import SimWorld

SMALL = {"width_px": 464, "height_px": 348, "pixel_pitch_um": 19.35}


def posed_world(motors):
    world = SimWorld(RigConfig.model_validate({"camera": SMALL}), get_model("lambert"), {"kd": 0.5})
    for name, value in zip(AXIS_NAMES, motors):
        world.axis_truth[name] = lambda value=value: value
    return world


def test_the_board_is_rendered_where_the_pinhole_model_puts_its_corners():
    """The ideal camera (no zero errors, mount or tilt) and the fit's model agree on every corner the detector
    finds, to a small fraction of a pixel."""
    pose = (20.0, 45.0, -115.0, 70.0)
    camera = SimCamera(posed_world(pose))
    board = BoardLayout()
    camera.show(board.scene())
    frame = camera.capture(0.1).pixels_dn
    image = cv2.normalize(frame, None, 0, 255, cv2.NORM_MINMAX).astype(np.uint8)
    corners, ids, _, _ = cv2.aruco.CharucoDetector(board.cv2_board()).detectBoard(image)
    assert ids is not None and len(ids) >= 40
    f = 50e-3 / 19.35e-6
    nominal = gf.start_values(gf.Camera(np.array([[f, 0, 231.5], [0, f, 173.5], [0, 0, 1]]), np.zeros(5)), 1.54)
    predicted = gf.project(gf.camera_points(nominal, np.array([pose]), board.sample_points()),
                           gf.intrinsics(nominal))[0][ids.ravel()]
    error = np.hypot(*(corners.reshape(-1, 2) - predicted).T)
    assert np.median(error) < 0.05 and error.max() < 0.3


def test_the_lamp_exit_is_a_disk_centred_on_the_lamp_and_dark_with_the_lamp_off():
    world = posed_world((0.0, 0.0, 90.0, 90.0))
    camera = SimCamera(world)
    window = camera.full_window()
    lum = lamp_exit_luminance(camera.optics, window, np.radians([0.0, 0.0, 90.0, 90.0]), np.eye(3), 0.92, 0.0375,
                              1.0)
    rows, cols = np.indices(lum.shape)
    weight = lum - lum.min()
    centre = (weight * cols).sum() / weight.sum() + 0.5, (weight * rows).sum() / weight.sum() + 0.5
    assert centre == pytest.approx((window.width / 2, window.height / 2), abs=0.01)
    camera.show("open")
    assert camera.luminance(Window(200, 150, 60, 40), 0.0).max() < 1.0        # the lamp is off


def test_a_scene_that_is_none_of_them_is_refused_and_changes_nothing():
    camera = SimCamera(lit_world())
    for bad in ("door", "open now", "board 9 7 0.02", "board 9 7 0.02 0.03 DICT_4X4_50"):
        with pytest.raises(DeviceError, match="scene"):
            camera.show(bad)
    assert camera.scene == "sample"


def test_the_served_camera_switches_its_scene_over_the_protocol():
    clock = SimClock()
    with CameraServer(lit_world(clock)) as server:
        client = ServedCamera(server.url, clock=clock)
        try:
            client.show("board 5 4 0.03 0.02 DICT_5X5_50")
            assert server.camera.scene == "board"
            assert server.camera.board == BoardLayout(5, 4, 0.03, 0.02, "DICT_5X5_50")
            with pytest.raises(DeviceError, match="refused 'SCENE door': scene 'door': one of"):
                client.show("door")
            client.show("sample")
            assert server.camera.scene == "sample"
        finally:
            client.close()
