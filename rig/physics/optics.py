"""Pinhole camera and lamp-spot optics of the goniophotometer (pure, vectorised numpy).

Shared by the planner, which must predict whether a point's ROI lies inside the
lit spot, and by the simulated camera, which renders what each pixel sees.
Radians and metres throughout.

Image convention: the camera sits at `distance_m * camera_unit(a, b)`, aimed at
the origin, oriented by `camera_frame(a, b)` = [sensor x | sensor y | backward].
Image columns grow along sensor x and image rows grow along *minus* sensor y, so
an image shown with row 0 at the top reads like a photograph taken by the
camera, not like its mirror: seen from the camera, sensor x is right and sensor
y up. For a pixel at image coordinates (u, v) (pixel edges at integers, centres
at +0.5) the sensor coordinates are sx = (u - width/2)·pitch,
sy = (v - height/2)·pitch and the ray direction is
normalize(-back·f + sx·x_axis - sy·y_axis).

The lamp beam is collimated: a cylinder of radius r along GCS Y through the
origin, so a point X is lit iff X_x² + X_z² ≤ r². On a sample tilted by θi the
spot is an ellipse with semi-axes r (along sample y at β = 0) and r / cos θi,
and the illuminance inside is E⊥ · cos θi.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.core.values import Window
from rig.physics.geometry import LAMP_DIRECTION_GCS, camera_frame, camera_unit, dot, sample_frame


@dataclass(frozen=True)
class CameraOptics:
    """Sensor size, pixel pitch (m), focal length (m) and camera-to-origin distance (m)."""

    width_px: int
    height_px: int
    pixel_pitch_m: float
    focal_length_m: float
    distance_m: float


def ray_directions(optics: CameraOptics, frame: np.ndarray, u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Unnormalised GCS directions (..., 3) of rays through image points (u, v).

    u, v: image coordinates in pixels (edges at integers, see module docstring);
    frame: camera_frame (..., 3, 3), whose leading axes broadcast with u and v.
    """
    sx = (np.asarray(u, float) - optics.width_px / 2) * optics.pixel_pitch_m
    sy = (np.asarray(v, float) - optics.height_px / 2) * optics.pixel_pitch_m
    return (sx[..., None] * frame[..., :, 0]
            + (-sy[..., None] * frame[..., :, 1] - optics.focal_length_m * frame[..., :, 2]))


def pixel_rays(optics: CameraOptics, a_rad: float, b_rad: float,
               window: Window) -> tuple[np.ndarray, np.ndarray]:
    """Camera centre (3,) and unit ray directions (height, width, 3) of the window's pixel centres, GCS."""
    cols = window.x0 + 0.5 + np.arange(window.width)
    rows = window.y0 + 0.5 + np.arange(window.height)
    rays = ray_directions(optics, camera_frame(a_rad, b_rad), cols[None, :], rows[:, None])
    rays /= np.sqrt(dot(rays, rays))[..., None]      # in place: full frames are 33 MB each
    return optics.distance_m * camera_unit(a_rad, b_rad), rays


def intersect_sample_plane(origin: np.ndarray, directions: np.ndarray,
                           normal_gcs: np.ndarray) -> np.ndarray:
    """Points (..., 3) where rays hit the front of the plane through the origin; NaN elsewhere.

    A ray hits the front only if the camera is on the normal's side and the
    ray travels against the normal; grazing, receding and rear rays give NaN.
    All arguments broadcast over their leading axes.
    """
    origin, directions, normal_gcs = (np.asarray(x, float) for x in (origin, directions, normal_gcs))
    height = dot(origin, normal_gcs)
    approach = dot(directions, normal_gcs)
    hit = (height > 0) & (approach < 0)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(hit, -height / approach, np.nan)
    points = t[..., None] * directions
    points += origin
    return points


def in_beam(points: np.ndarray, radius_m: float) -> np.ndarray:
    """True where GCS points (..., 3) lie inside the collimated beam; False for NaN points.

    A negative radius (a margin wider than the spot) lights nothing.
    """
    points = np.asarray(points, float)
    return (radius_m >= 0) & (points[..., 0] ** 2 + points[..., 2] ** 2 <= radius_m ** 2)


def faces_lamp(normal_gcs: np.ndarray) -> np.ndarray:
    """True where the lamp shines on the front of the sample (cos θi > 0)."""
    return np.asarray(normal_gcs, float) @ LAMP_DIRECTION_GCS > 0


def roi_inside_spot(stage_vertical_rad: np.ndarray, stage_normal_rad: np.ndarray,
                    arm_azimuth_rad: np.ndarray, arm_polar_rad: np.ndarray,
                    roi_px: int, optics: CameraOptics, spot_radius_m: float,
                    margin_m: float = 0.0) -> np.ndarray:
    """Whether the central roi_px × roi_px pixels see only lit sample, for each pose.

    The four outer corners of the ROI (Window.centred) must hit the front of
    the sample plane inside the beam shrunk by `margin_m`, and the lamp must
    light the front. Corners suffice: the projected ROI is a convex
    quadrilateral and the lit spot is convex. Motor angles broadcast together.
    """
    roi = Window.centred(optics.width_px, optics.height_px, roi_px, roi_px)
    u = np.array([roi.x0, roi.x0 + roi.width, roi.x0, roi.x0 + roi.width], float)
    v = np.array([roi.y0, roi.y0, roi.y0 + roi.height, roi.y0 + roi.height], float)
    alpha, beta, a, b = np.broadcast_arrays(*(np.asarray(x, float) for x in (
        stage_vertical_rad, stage_normal_rad, arm_azimuth_rad, arm_polar_rad)))
    corners = ray_directions(optics, camera_frame(a, b)[..., None, :, :], u, v)   # (..., 4, 3)
    origin = optics.distance_m * camera_unit(a, b)
    normal = sample_frame(alpha, beta)[..., :, 2]
    points = intersect_sample_plane(origin[..., None, :], corners, normal[..., None, :])
    return faces_lamp(normal) & np.all(in_beam(points, spot_radius_m - margin_m), axis=-1)
