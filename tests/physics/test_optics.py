"""Closed-form checks of the pinhole camera and lamp-spot optics (rig.physics.optics).

The speed of roi_inside_spot is a benchmark (benchmarks/hot_paths.py), not a test.
"""

import dataclasses

import numpy as np
import pytest

from rig.config.rigfile import RigConfig, camera_optics
from rig.core.values import Window
from rig.physics.geometry import camera_unit, inverse_deg, sample_frame
from rig.physics.optics import in_beam, intersect_sample_plane, pixel_rays, roi_inside_spot

CFG = RigConfig()
OPTICS = camera_optics(CFG)
FULL = Window(0, 0, OPTICS.width_px, OPTICS.height_px)
R_SPOT = CFG.geometry.spot_diameter_m / 2
#: Size of one pixel on a fronto-parallel plane through the origin (m).
PX_ON_SAMPLE = OPTICS.pixel_pitch_m * OPTICS.distance_m / OPTICS.focal_length_m


def motor_rad(theta_i, phi_i, theta_o, phi_o):
    """Motor angles (radians, each of the broadcast shape) for BRDF angles in degrees."""
    return tuple(np.radians(inverse_deg(theta_i, phi_i, theta_o, phi_o).as_array()).T)


def sample_points(alpha, beta, a, b, window=FULL):
    """Sample-plane points seen by the window's pixels: GCS (h, w, 3) and sample (x, y) (h, w, 2)."""
    origin, rays = pixel_rays(OPTICS, a, b, window)
    frame = sample_frame(alpha, beta)
    points = intersect_sample_plane(origin, rays, frame[:, 2])
    return points, points @ frame[:, :2]


def test_from_config_converts_units():
    assert (OPTICS.width_px, OPTICS.height_px) == (1390, 1040)
    assert dataclasses.astuple(OPTICS)[2:] == pytest.approx((6.45e-6, 0.05, 1.54), rel=1e-12)


@pytest.mark.parametrize("a_deg, b_deg", [(0, 0), (-90, 90), (37, -61), (150, 20)])
def test_camera_sits_on_its_arm_and_looks_at_origin(a_deg, b_deg):
    a, b = np.radians([a_deg, b_deg])
    centre = Window.centred(OPTICS.width_px, OPTICS.height_px, 2, 2)   # 4 pixels round the axis
    origin, rays = pixel_rays(OPTICS, a, b, centre)
    np.testing.assert_allclose(origin, 1.54 * camera_unit(a, b), atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(rays, axis=-1), 1.0, rtol=1e-14)
    axis = rays.mean(axis=(0, 1))
    np.testing.assert_allclose(axis / np.linalg.norm(axis), -camera_unit(a, b), atol=1e-14)
    assert rays.shape == (2, 2, 3)


def test_image_orientation_is_a_photograph_not_a_mirror():
    # Sample at home, camera on its normal: sample +x at the top, sample +y on the left.
    _, xy = sample_points(0.0, 0.0, *np.radians([-90.0, 90.0]))
    assert xy[0, 0, 0] > 0.1 and xy[-1, 0, 0] < -0.1                # +x up (row 0)
    assert xy[0, 0, 1] > 0.13 and xy[0, -1, 1] < -0.13              # +y left (col 0)
    np.testing.assert_allclose(xy[:, 0, 1], xy[0, 0, 1], rtol=1e-12)  # rows run along x only


@pytest.mark.parametrize("angles", [(0, 0, 30, 10), (45, 120, 60, 250), (70, 300, 20, 90)])
def test_image_to_sample_map_preserves_orientation(angles):
    # (col, -row) is right/up in the image; sample (x, y) is right/up seen from the front.
    _, xy = sample_points(*motor_rad(*angles), Window(600, 500, 2, 2))
    d_col = xy[0, 1] - xy[0, 0]
    d_up = xy[0, 0] - xy[1, 0]
    assert d_col[0] * d_up[1] - d_col[1] * d_up[0] > 0


def test_scale_at_normal_view_is_pitch_times_distance_over_focal_length():
    roi = Window.centred(OPTICS.width_px, OPTICS.height_px, 70, 70)
    _, xy = sample_points(*motor_rad(30, 0, 0, 0), roi)
    width = np.linalg.norm(xy[35, -1] - xy[35, 0])                     # 69 pixel steps
    assert width == pytest.approx(69 * PX_ON_SAMPLE, rel=1e-9)
    assert 70 * PX_ON_SAMPLE == pytest.approx(13.9e-3, abs=0.05e-3)


def test_intersect_sample_plane_front_only():
    normal = np.array([0.0, 0.0, 1.0])
    origin = np.array([0.0, 0.0, 2.0])
    dirs = np.array([[0.0, 0.0, -1.0], [1.0, 0.0, -1.0], [0.0, 0.3, 1.0], [1.0, 0.0, 0.0]])
    points = intersect_sample_plane(origin, dirs, normal)
    np.testing.assert_allclose(points[:2], [[0, 0, 0], [2, 0, 0]], atol=1e-15)
    assert np.isnan(points[2:]).all()                                   # receding, grazing
    behind = intersect_sample_plane(-origin, dirs[:2], normal)          # camera behind the sample
    assert np.isnan(behind).all()
    many = intersect_sample_plane(origin, dirs[:2], np.tile(normal, (5, 1, 1)))
    assert many.shape == (5, 2, 3)


@pytest.mark.parametrize("theta_i", [0.0, 45.0, 60.0])
def test_lit_footprint_is_ellipse_r_by_r_over_cos_theta_i(theta_i):
    points, xy = sample_points(*motor_rad(theta_i, 0, 0, 0))          # camera on the normal
    lit = in_beam(points, R_SPOT)
    semi_x = np.abs(xy[lit][:, 0]).max()
    semi_y = np.abs(xy[lit][:, 1]).max()
    assert semi_x == pytest.approx(R_SPOT / np.cos(np.radians(theta_i)), abs=PX_ON_SAMPLE)
    assert semi_y == pytest.approx(R_SPOT, abs=PX_ON_SAMPLE)
    radius2 = (xy[..., 0] * np.cos(np.radians(theta_i))) ** 2 + xy[..., 1] ** 2
    # pixels within round-off of the rim may fall either way (two computations, any CPU's kernels)
    clear = np.abs(radius2 - R_SPOT ** 2) > 1e-9 * R_SPOT ** 2
    assert clear.mean() > 0.99
    np.testing.assert_array_equal(lit[clear], (radius2 <= R_SPOT ** 2)[clear])


def test_roi_inside_spot_at_normal_view_and_not_at_grazing_view():
    # At θi = 0 the spot is a 75 mm circle; viewed at θo it spans 75·cos θo mm across the
    # view, against a 70 px ≈ 13.9 mm ROI: in up to ~79°, out beyond (along the image axes).
    theta_o = np.array([0.0, 30.0, 60.0, 75.0, 78.0, 80.0, 85.0])
    expected = theta_o < 79.0
    for phi_o in (0.0, 90.0, 180.0):
        got = roi_inside_spot(*motor_rad(0, 0, theta_o, phi_o), 70, OPTICS, R_SPOT)
        np.testing.assert_array_equal(got, expected)


def test_roi_inside_spot_fails_behind_the_sample_or_the_lamp():
    views = roi_inside_spot(*motor_rad(0, 0, [89.0, 91.0, 120.0], 0), 70, OPTICS, R_SPOT)
    assert not views.any()
    edge_on = roi_inside_spot(np.radians(90.0), 0.0, *np.radians([-90.0, 90.0]), 70, OPTICS, R_SPOT)
    assert not edge_on
    # θi = 100°: the camera faces the sample and the ROI lies in the beam, but the lamp is behind.
    lit_from_behind = roi_inside_spot(*np.radians([100.0, 0.0, 10.0, 90.0]), 70, OPTICS, R_SPOT)
    assert not lit_from_behind
    assert roi_inside_spot(*np.radians([80.0, 0.0, -10.0, 90.0]), 70, OPTICS, R_SPOT)


def test_margin_shrinks_the_spot_to_the_roi_corners():
    # Normal view at θi = 0: the ROI's half-diagonal is 35·√2 pixels on the sample.
    half_diagonal = 35 * np.sqrt(2) * PX_ON_SAMPLE
    pose = motor_rad(0, 0, 0, 0)
    assert roi_inside_spot(*pose, 70, OPTICS, R_SPOT, margin_m=R_SPOT - half_diagonal - 1e-5)
    assert not roi_inside_spot(*pose, 70, OPTICS, R_SPOT, margin_m=R_SPOT - half_diagonal + 1e-5)
    assert not roi_inside_spot(*pose, 70, OPTICS, R_SPOT, margin_m=2 * R_SPOT)


def test_roi_prediction_agrees_with_the_pixels():
    rng = np.random.default_rng(3)
    angles = rng.uniform([0, 0, 70, 0], [80, 360, 88, 360], (60, 4)).T            # near the edge
    poses = np.stack(motor_rad(*angles), axis=-1)
    predicted = roi_inside_spot(*poses.T, 70, OPTICS, R_SPOT)
    assert 5 < predicted.sum() < 55                                      # both outcomes occur
    roi = Window.centred(OPTICS.width_px, OPTICS.height_px, 70, 70)
    for pose, pred in zip(poses, predicted):
        points, _ = sample_points(*pose, roi)
        assert in_beam(points, R_SPOT).all() or not pred   # a predicted-lit ROI has every pixel lit


def test_roi_inside_spot_is_vectorised():
    rng = np.random.default_rng(0)
    n = 3000
    poses = motor_rad(*rng.uniform([0, 0, 0, 0], [85, 360, 89, 360], (n, 4)).T)
    one_by_one = [bool(roi_inside_spot(*(p[i] for p in poses), 70, OPTICS, R_SPOT)) for i in range(20)]
    result = roi_inside_spot(*poses, 70, OPTICS, R_SPOT)
    assert result.shape == (n,) and result.dtype == bool
    assert list(result[:20]) == one_by_one
