"""What the simulated camera sees during `rig calibrate geometry` (docs/geometry-calibration.md): the ChArUco board
on the sample holder under the room's lights, or, with the holder empty, the lamp's exit seen from across the
goniometer. Pure rendering of luminance; the sensor model (rig.simulators.sensor) adds noise afterwards.

Everything is rendered at the world's truth: the axes' physical angles (encoder plus zero error), the holder's
tilt and the camera's mount (SimWorld.holder_tilt, SimWorld.camera_mount). Each pixel is the mean of SUPERSAMPLE²
rays through it (a printed edge falls part-way across a pixel), then the image is blurred by the lens's defocus
(BLUR_PX), so that a corner's image is where the pinhole model puts it, to well under a tenth of a pixel.
"""

from __future__ import annotations

import functools

import numpy as np
from scipy.ndimage import gaussian_filter, map_coordinates

from rig.core.values import Window
from rig.physics.charuco_board import BoardLayout
from rig.physics.geometry import camera_frame, camera_unit
from rig.physics.optics import CameraOptics

#: Rays per pixel along each side.
SUPERSAMPLE = 2
#: Standard deviation (px) of the lens's blur at the board's distance: the camera is focused on the sample plane.
BLUR_PX = 0.6
#: The board's white under the room's lights, its black (printed toner reflects ~4 %), and the holder around it.
BOARD_WHITE_CD_M2 = 80.0
BOARD_BLACK_CD_M2 = 3.0
HOLDER_CD_M2 = 10.0
#: The lamp's exit with its diffuser, at the lamp's nominal output, and the dark room behind.
LAMP_EXIT_CD_M2 = 2000.0
ROOM_CD_M2 = 0.2
#: Bitmap pixels per board square: 0.2 mm on the default board, finer than a camera pixel's footprint.
PX_PER_SQUARE = 100
#: The bitmap is smoothed by this much (bitmap px) before it is sampled, so that rays spaced wider than its
#: pixels still find each printed edge where it is (no aliasing); the lens's blur is far wider anyway.
BITMAP_BLUR_PX = 1.5


@functools.lru_cache(maxsize=4)
def _bitmap(layout: BoardLayout) -> np.ndarray:
    """The board's luminance map (cd/m²), one value per bitmap pixel."""
    printed = gaussian_filter(layout.bitmap(PX_PER_SQUARE).astype(float) / 255.0, BITMAP_BLUR_PX)
    return BOARD_BLACK_CD_M2 + (BOARD_WHITE_CD_M2 - BOARD_BLACK_CD_M2) * printed


def _rays(optics: CameraOptics, window: Window, arm_rad: tuple[float, float], mount: np.ndarray,
          vectors: np.ndarray) -> tuple[np.ndarray, list[np.ndarray]]:
    """Camera centre (3,) and, for each of `vectors` (k, 3), d·q over the window's sub-pixels (height·S, width·S),
    d the unnormalised GCS ray d = sx·X − sy·Y − f·B (camera frame [X | Y | B]): an outer sum of a row and a
    column term, so that no (height·S, width·S, 3) array is made."""
    a, b = arm_rad
    cam = camera_frame(a, b) @ mount
    offsets = (np.arange(SUPERSAMPLE) + 0.5) / SUPERSAMPLE
    sx = (window.x0 + np.add.outer(np.arange(window.width), offsets).ravel() - optics.width_px / 2)
    sy = (window.y0 + np.add.outer(np.arange(window.height), offsets).ravel() - optics.height_px / 2)
    x, y, back = (np.asarray(vectors, float) @ cam).T
    pitch, f = optics.pixel_pitch_m, optics.focal_length_m
    dots = [np.add.outer(-sy * (pitch * yq) - f * bq, sx * (pitch * xq)) for xq, yq, bq in zip(x, y, back)]
    return optics.distance_m * camera_unit(a, b), dots


def _pixels(sub: np.ndarray, window: Window) -> np.ndarray:
    """Sub-pixel values → pixel means, blurred by the lens."""
    mean = sub.reshape(window.height, SUPERSAMPLE, window.width, SUPERSAMPLE).mean(axis=(1, 3))
    return gaussian_filter(mean, BLUR_PX, mode="nearest")


def board_luminance(optics: CameraOptics, window: Window, layout: BoardLayout, motors_rad: np.ndarray,
                    holder: np.ndarray, mount: np.ndarray) -> np.ndarray:
    """Luminance (cd/m², (height, width)) of the board on the holder whose frame is `holder` (the sample frame
    at the true stage angles, tilted), seen with the arm at the true angles `motors_rad[2:]`."""
    normal = holder[:, 2]
    origin, (along, dx, dy) = _rays(optics, window, (motors_rad[2], motors_rad[3]), mount, holder[:, [2, 0, 1]].T)
    height = float(origin @ normal)
    lum = np.full(along.shape, HOLDER_CD_M2)
    if height <= 0:                                    # the camera is behind the holder
        return _pixels(lum, window)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(along < 0, -height / along, np.nan)     # NaN where the ray misses the plane
    xs, ys = origin @ holder[:, 0] + t * dx, origin @ holder[:, 1] + t * dy
    width_m, height_m = layout.size_m
    scale = PX_PER_SQUARE / layout.square_m            # bitmap pixels per metre
    col, row = (xs + width_m / 2) * scale - 0.5, (height_m / 2 - ys) * scale - 0.5
    bitmap = _bitmap(layout)
    rows, cols = bitmap.shape
    on = np.isfinite(t) & (col >= -0.5) & (row >= -0.5) & (col <= cols - 0.5) & (row <= rows - 0.5)
    lum[on] = map_coordinates(bitmap, [row[on], col[on]], order=1, mode="nearest")
    return _pixels(lum, window)


def lamp_exit_luminance(optics: CameraOptics, window: Window, motors_rad: np.ndarray, mount: np.ndarray,
                        lamp_distance_m: float, radius_m: float, output: float) -> np.ndarray:
    """Luminance (cd/m², (height, width)) of the lamp's exit (a disk of `radius_m` about (0, −d, 0) facing +Y,
    LAMP_EXIT_CD_M2 × the lamp's relative `output`) in a dark room, the holder empty."""
    origin, (dx, dy, dz) = _rays(optics, window, (motors_rad[2], motors_rad[3]), mount, np.eye(3))
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(dy < 0, (-lamp_distance_m - origin[1]) / dy, np.nan)
    x, z = origin[0] + t * dx, origin[2] + t * dz
    with np.errstate(invalid="ignore"):
        lit = x * x + z * z <= radius_m ** 2
    return _pixels(np.where(lit, LAMP_EXIT_CD_M2 * output, ROOM_CD_M2), window)
