"""The goniometer model fit (rig.physics.goniometer_fit) on closed-form synthetic views: corners and lamp centroids
projected from a known model, with noise of a known size."""

import numpy as np
import pytest

from rig.physics import goniometer_fit as gf
from rig.physics.charuco_board import BoardLayout

POINTS = BoardLayout().sample_points()
CAMERA = gf.Camera(np.array([[2584.0, 0.0, 231.5], [0.0, 2584.0, 173.5], [0.0, 0.0, 1.0]]), np.zeros(5))
CORNER_NOISE_PX, LAMP_NOISE_PX = 0.05, 0.02


def _truth(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    truth = gf.start_values(CAMERA, 1.54)
    truth[:4] += rng.normal(0.0, 0.3, 4)              # axis zeros
    truth[4:7] += rng.normal(0.0, 0.1, 3)             # holder tilt, camera roll
    truth[7] += 0.002                                 # camera distance
    truth[8:11] += rng.normal(0.0, 0.001, 3)          # board offset on the holder
    truth[11:15] += rng.normal(0.0, 2.0, 4)           # focal lengths and principal point
    return truth


def _views(truth: np.ndarray, seed: int, boards=None, lamps=None):
    rng = np.random.default_rng(seed + 1000)
    default_boards, default_lamps = gf.calibration_poses()
    boards = default_boards if boards is None else boards
    lamps = default_lamps if lamps is None else lamps
    camera = gf.intrinsics(truth)
    board_views = [gf.BoardView(f"board-{i}", m, np.arange(len(POINTS)),
                                gf.project(gf.camera_points(truth, np.array([m]), POINTS), camera)[0]
                                + rng.normal(0.0, CORNER_NOISE_PX, (len(POINTS), 2)))
                   for i, m in enumerate(boards)]
    lamp_views = [gf.LampView(f"lamp-{i}", m, gf.predict_lamp(truth, np.array([m]), 0.92)[0]
                              + rng.normal(0.0, LAMP_NOISE_PX, 2)) for i, m in enumerate(lamps)]
    return board_views, lamp_views


def _fit(boards, lamps):
    return gf.fit(boards, lamps, POINTS, CAMERA, camera_distance_m=1.54, lamp_distance_m=0.92)


@pytest.mark.parametrize("seed", [1, 2])
def test_fit_recovers_the_model_and_its_uncertainty_covers_the_truth(seed):
    truth = _truth(seed)
    result = _fit(*_views(truth, seed))
    error = result.values - truth
    assert np.all(np.abs(error) <= 3 * result.u), dict(zip(gf.PARAMETERS, error / result.u))
    assert np.all(np.abs(error[:4]) < 0.005)                           # every axis zero, degrees
    assert np.all(result.u[:4] < 0.005)
    assert result.corner_sigma_px == pytest.approx(CORNER_NOISE_PX, rel=0.15)
    assert not result.rejected


def test_a_view_the_model_does_not_explain_is_rejected_with_its_reason():
    truth = _truth(3)
    boards, lamps = _views(truth, 3)
    slipped = boards[4]
    boards[4] = gf.BoardView(slipped.label, slipped.motors_deg, slipped.ids, slipped.image_px + [2.0, -1.5])
    result = _fit(boards, lamps)
    assert list(result.rejected) == ["board-4"]
    assert "residual RMS" in result.rejected["board-4"]
    assert np.all(np.abs(result.values - truth) <= 3 * result.u)


def test_without_lamp_views_the_fit_says_what_to_add():
    boards, _ = _views(_truth(4), 4)
    with pytest.raises(gf.FitError, match="camera opposite the lamp"):
        _fit(boards, [])


def test_too_few_board_views_are_refused():
    boards, lamps = _views(_truth(5), 5)
    with pytest.raises(gf.FitError, match="at least 6 are needed"):
        _fit(boards[:5], lamps)


def test_a_degenerate_pose_set_names_the_parameters_it_cannot_tell_apart():
    """The stage never turns: its vertical axis's zero cannot be told from the holder's tilt."""
    truth = _truth(6)
    same = [(0.0, 0.0, -90.0 + side, 70.0) for side in (-40.0, -20.0, 0.0, 20.0, 40.0, 10.0)]
    with pytest.raises(gf.FitError, match="degenerate pose set: the views cannot tell stage_vertical_zero_deg, "
                                          "tilt_y_deg apart"):
        _fit(*_views(truth, 6, boards=same))


def test_a_model_far_from_the_views_is_refused():
    """The rig file's lamp distance 30 cm off: the corners fit, the lamp views cannot, and are rejected until
    too few are left."""
    truth = _truth(7)
    boards, lamps = _views(truth, 7)
    with pytest.raises(gf.FitError, match="lamp-.* rejected .*residual RMS.* lamp views left, at least 2"):
        gf.fit(boards, lamps, POINTS, CAMERA, camera_distance_m=1.54, lamp_distance_m=0.62)
