"""The geometric calibration of a goniometer with a ChArUco board (docs/geometry-calibration.md): drive the stage
and arm through the board views and the lamp views, find the board's corners (cv2.aruco.CharucoDetector) and the
lamp exit's centroid, solve the camera's intrinsics (cv2.calibrateCamera) and each view's board pose (solvePnP,
a check that the corners fit a flat board), then fit the goniometer model (rig.physics.goniometer_fit).

The procedure talks to the rig's devices and to `show`, which puts a scene before the camera: on the simulated
rig its camera's scene switch, on a real rig a prompt to the operator (mount the board, empty the holder). Which
is the caller's (`rig calibrate geometry`, rig.cli.calibrate_geometry). Moves here are in encoder readings, the
frame the calibration is found in, whatever calibration the rig file already names.
"""

from __future__ import annotations

import datetime
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Literal

import cv2
import numpy as np
from scipy.ndimage import binary_dilation

from rig.config.geometry_calibration import (
    BoardEntry,
    Estimate,
    FitEntry,
    GeometryCalibration,
    IntrinsicsEntry,
    ViewEntry,
    covariance_list,
)
from rig.config.rigfile import RigConfig
from rig.core.values import SensorInfo
from rig.drivers.interfaces import LampSupply, LuminanceCamera, RigDevices
from rig.physics import goniometer_fit as gf
from rig.physics.charuco_board import BoardLayout
from rig.planning.collisions import path_crosses, zones_of
from rig.planning.ordering import travel_time_s
from rig.planning.points import Motors

METHOD = ("ChArUco board on the sample holder (cv2.aruco.CharucoDetector), intrinsics by cv2.calibrateCamera, "
          "goniometer model (axis zeros, holder tilt, camera mount and distance, board offset) by a weighted "
          "least-squares bundle over the corners and the lamp exit's centroids")
#: A long lens's narrow field cannot tell higher distortion terms from the principal point: k1 only.
INTRINSIC_FLAGS = cv2.CALIB_FIX_K2 | cv2.CALIB_FIX_K3 | cv2.CALIB_ZERO_TANGENT_DIST
#: A view needs this many corners to count.
MIN_CORNERS = 8
#: A view whose corners a flat board's pose (solvePnP) leaves with a larger RMS is rejected.
PNP_REJECT_PX = 1.0
#: The brightest part of a frame is exposed to this fraction of the sensor's range.
EXPOSE_FRACTION = 0.6
METERING_STEPS = 5
#: Moves may take this much longer than predicted before an axis counts as stuck.
MOVE_TIMEOUT_FACTOR, MOVE_TIMEOUT_MARGIN_S = 2.0, 10.0


class GeometryCalibrationError(Exception):
    """The procedure cannot give a calibration; the message says what to change."""


@dataclass
class _Seen:
    """One view as taken: its axes (encoder readings) and what was found, or why it does not count."""

    label: str
    kind: Literal["board", "lamp"]
    motors_deg: Motors
    ids: np.ndarray | None = None
    points_px: np.ndarray | None = None
    rejected: str | None = None

    def found(self) -> tuple[np.ndarray, np.ndarray]:
        """The corner ids (none for a lamp view) and the points found (px) of a view that counts."""
        assert self.points_px is not None, "only a view that counts is fitted"
        return (np.zeros(0, int) if self.ids is None else self.ids), self.points_px

    @property
    def count(self) -> int:
        return 0 if self.points_px is None else len(self.points_px)


def measure(devices: RigDevices, config: RigConfig, board: BoardLayout, *, show: Callable[[str], None],
            board_poses: list[Motors], lamp_poses: list[Motors],
            progress: Callable[[str], None] = lambda text: None) -> GeometryCalibration:
    """Run the procedure (module docstring) and return the calibration; GeometryCalibrationError naming what to
    change when the views cannot give one. The lamp is switched off again before this returns or raises."""
    detector = cv2.aruco.CharucoDetector(board.cv2_board())
    sensor = devices.camera.sensor
    if devices.attenuator is not None and config.attenuator is not None:
        clearest = max(config.attenuator.filters, key=lambda f: f.transmission)       # the board is dim
        devices.attenuator.move_to(clearest.position)
    show(board.scene())
    boards = _take_views(devices, config, "board", board_poses, lambda take: _corners(detector, take(), sensor),
                         lambda seen: f"{seen.count} corners", progress)
    found = [s for s in boards if s.rejected is None]
    if not found:
        raise GeometryCalibrationError(f"the board was not found in any of the {len(boards)} views: check that it "
                                       "lies on the sample holder, lit, in the camera's view, and that --board "
                                       "describes it")
    show("open")
    lamps = _lamp_views(devices, config, lamp_poses, progress)
    show("sample")
    intrinsics, matrix, distortion = _intrinsics(board, found, sensor)
    _check_flat(board, found, matrix, distortion)
    used_boards = [s for s in boards if s.rejected is None]
    used_lamps = [s for s in lamps if s.rejected is None]
    if len(used_boards) < 6:
        raise GeometryCalibrationError(f"too few poses: the board was usable in {len(used_boards)} of "
                                       f"{len(boards)} views, at least 6 are needed; see why above")
    try:
        fit = gf.fit([gf.BoardView(s.label, s.motors_deg, *s.found()) for s in used_boards],
                     [gf.LampView(s.label, s.motors_deg, s.found()[1][0]) for s in used_lamps],
                     board.sample_points(), gf.Camera(matrix, distortion),
                     camera_distance_m=config.geometry.camera_distance_m,
                     lamp_distance_m=config.geometry.lamp_distance_m)
    except gf.FitError as exc:
        raise GeometryCalibrationError(str(exc)) from None
    for s in boards + lamps:
        if s.label in fit.rejected:
            s.rejected = fit.rejected[s.label]
    views = [ViewEntry(label=s.label, kind=s.kind, motors_deg=s.motors_deg, points=s.count,
                       rms_px=fit.view_rms_px.get(s.label) if s.rejected is None else None, rejected=s.rejected)
             for s in boards + lamps]
    (px, upx), (py, upy) = gf.pointing_deg(fit.values, fit.covariance, sensor.width_px, sensor.height_px)
    return GeometryCalibration(
        rig=config.name, date=datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        method=METHOD, board=BoardEntry(**vars(board)), intrinsics=intrinsics,
        parameters={name: Estimate(value=v, u=u) for name, (v, u) in fit.named().items()},
        pointing_x_deg=Estimate(value=px, u=upx), pointing_y_deg=Estimate(value=py, u=upy),
        covariance=covariance_list(fit.covariance),
        fit=FitEntry(corner_sigma_px=fit.corner_sigma_px, lamp_sigma_px=fit.lamp_sigma_px, views=views))


def _move(devices: RigDevices, config: RigConfig, pose: Motors) -> str | None:
    """Drive the four axes to `pose` (encoder readings) and wait; why not, for a pose the rig forbids."""
    limits = config.axes.limits()
    for value, name in zip(pose, ("stage_vertical", "stage_normal", "arm_azimuth", "arm_polar")):
        lo, hi = getattr(limits, name)
        if not lo <= value <= hi:
            return f"{name} {value:g}° is outside the axis limits [{lo:g}, {hi:g}]°"
    here = _read_back(devices)
    zone = path_crosses(here, pose, zones_of(config), config.axes)
    if zone is not None:
        return f"the move there would cross forbidden zone {zone!r}"
    devices.stage.start_move(pose[0], pose[1])
    devices.arm.start_move(pose[2], pose[3])
    timeout = MOVE_TIMEOUT_FACTOR * float(travel_time_s(config.axes, np.asarray(here), np.asarray(pose))) \
        + MOVE_TIMEOUT_MARGIN_S
    devices.stage.wait(timeout)
    devices.arm.wait(timeout)
    return None


def _read_back(devices: RigDevices) -> Motors:
    stage, arm = devices.stage.positions_deg(), devices.arm.positions_deg()
    return stage[0], stage[1], arm[0], arm[1]


def _meter(camera: LuminanceCamera, sensor: SensorInfo) -> float:
    """An exposure that puts the frame's brightest 0.5 % at EXPOSE_FRACTION of the sensor's range."""
    span = 2 ** sensor.bit_depth - 1 - sensor.black_level_dn
    t = float(np.sqrt(sensor.min_exposure_s * min(sensor.max_exposure_s, 1.0)))
    for _ in range(METERING_STEPS):
        bright = float(np.percentile(camera.capture(t).pixels_dn, 99.5)) - sensor.black_level_dn
        wanted = float(np.clip(t * EXPOSE_FRACTION * span / max(bright, 1.0), sensor.min_exposure_s,
                               sensor.max_exposure_s))
        if 0.4 * span <= bright <= 0.8 * span or wanted == t:
            return t
        t = wanted if bright < 0.95 * span else max(t / 8, sensor.min_exposure_s)
    return t


def _eight_bit(pixels: np.ndarray, sensor: SensorInfo) -> np.ndarray:
    """The frame above black, scaled so that its brightest 0.5 % is white: what the detector reads."""
    signal = pixels.astype(float) - sensor.black_level_dn
    top = max(float(np.percentile(signal, 99.5)), 1.0)
    return np.clip(signal * (255.0 / top), 0, 255).astype(np.uint8)


def _corners(detector: cv2.aruco.CharucoDetector, pixels: np.ndarray,
             sensor: SensorInfo) -> tuple[np.ndarray | None, np.ndarray | None, str | None]:
    """The chessboard corners found (ids, (N, 2) px) or why the view does not count."""
    corners, ids, _, _ = detector.detectBoard(_eight_bit(pixels, sensor))
    count = 0 if ids is None else len(ids)
    if count == 0:
        return None, None, "board not found"
    if count < MIN_CORNERS:
        return None, None, f"only {count} corners found, {MIN_CORNERS} needed"
    return ids.ravel().astype(int), corners.reshape(-1, 2).astype(float), None


def lamp_centroid(pixels: np.ndarray, sensor: SensorInfo) -> tuple[np.ndarray | None, str | None]:
    """The centroid (x, y; OpenCV pixel coordinates) of the lamp exit's image, or why there is none: the pixels
    over half-way from the background to the exit's plateau, grown by 3 px so that its blurred edge counts
    whole, each weighted by its fraction of the plateau (a symmetric weight: no bias for a round exit)."""
    signal = pixels.astype(float) - sensor.black_level_dn
    background, plateau = float(np.median(signal)), float(np.percentile(signal, 99.9))
    noise = max(float(np.std(signal[signal < np.percentile(signal, 50)])), 1.0)
    if plateau - background < 20 * noise:
        return None, "lamp exit not found (is the lamp on and the holder empty?)"
    bright = signal > background + 0.5 * (plateau - background)
    region = binary_dilation(bright, iterations=3)
    if region[0].any() or region[-1].any() or region[:, 0].any() or region[:, -1].any():
        return None, "the lamp exit's image touches the frame's edge"
    weight = np.where(region, np.clip((signal - background) / (plateau - background), 0, 1), 0.0)
    rows, cols = np.indices(signal.shape)
    total = weight.sum()
    return np.array([(weight * cols).sum() / total, (weight * rows).sum() / total]), None


#: What a view's picture gives: the corner ids (None for a lamp view), the points found (px), or why none count.
Found = tuple[np.ndarray | None, np.ndarray | None, str | None]


def _take_views(devices: RigDevices, config: RigConfig, kind: Literal["board", "lamp"], poses: list[Motors],
                find: Callable[[Callable[[], np.ndarray]], Found], describe: Callable[[_Seen], str],
                progress: Callable[[str], None]) -> list[_Seen]:
    """Each pose in turn: move, read the axes back, and let `find` look in the picture its argument takes (at the
    exposure metered on the first pose); a pose the rig cannot reach is kept as rejected, with why."""
    camera, sensor = devices.camera, devices.camera.sensor
    views: list[_Seen] = []
    exposure: float | None = None
    for i, pose in enumerate(poses):
        seen = _Seen(f"{kind}-{i + 1:02d}", kind, pose)
        if (why := _move(devices, config, pose)) is not None:
            seen.rejected = why
        else:
            seen.motors_deg = _read_back(devices)
            exposure = exposure or _meter(camera, sensor)
            seen.ids, seen.points_px, seen.rejected = find(partial(_picture, camera, exposure))
        progress(f"{seen.label}: {seen.rejected or describe(seen)}")
        views.append(seen)
    return views


def _picture(camera: LuminanceCamera, exposure_s: float) -> np.ndarray:
    return camera.capture(exposure_s).pixels_dn


def _lamp_exit(take: Callable[[], np.ndarray], sensor: SensorInfo, lamp: LampSupply, config: RigConfig,
               progress: Callable[[str], None]) -> Found:
    """A lamp view's find: the exit's centroid as the one point, or why there is none. An exit not found is asked
    of the supply: an output the supply switched off itself (its communication watchdog, after the computer
    stalled) is switched on again and the picture taken once more; one held off by something else (an interlock,
    a fault) is named."""
    centroid, why = lamp_centroid(take(), sensor)
    if centroid is None and (loss := lamp.output_loss()) is not None:
        why = f"lamp exit not found: the lamp is off: {loss.reason}"
        if loss.restart:
            progress(f"the lamp is off: {loss.reason}; switched on again, the picture taken once more")
            _light(lamp, config)
            centroid, again = lamp_centroid(take(), sensor)
            why = None if again is None else f"{why}; switched on again: {again}"
    return None, (None if centroid is None else centroid[None, :]), why


def _light(lamp: LampSupply, config: RigConfig) -> None:
    """The lamp on at the rig file's current, ramped up from zero."""
    lamp.set_current(0.0)
    lamp.set_output(True)
    lamp.set_current(config.lamp.current_a, ramp_s=config.lamp.ramp_s)


def _lamp_views(devices: RigDevices, config: RigConfig, poses: list[Motors],
                progress: Callable[[str], None]) -> list[_Seen]:
    """The lamp views, the lamp on for them and off afterwards whatever happens."""
    lamp, sensor = devices.lamp, devices.camera.sensor
    views: list[_Seen] = []
    try:
        _light(lamp, config)
        views = _take_views(devices, config, "lamp", poses,
                            lambda take: _lamp_exit(take, sensor, lamp, config, progress),
                            lambda seen: "lamp exit at ({:.2f}, {:.2f}) px".format(*seen.found()[1][0]), progress)
    finally:
        lamp.set_output(False)
    return views


def _intrinsics(board: BoardLayout, views: list[_Seen],
                sensor: SensorInfo) -> tuple[IntrinsicsEntry, np.ndarray, np.ndarray]:
    """cv2.calibrateCamera over the board views (INTRINSIC_FLAGS)."""
    points = board.board_points()
    objects = [points[s.found()[0]].astype(np.float32) for s in views]
    images = [s.found()[1].astype(np.float32) for s in views]
    size = (sensor.width_px, sensor.height_px)
    try:
        rms, matrix, distortion, _, _ = cv2.calibrateCamera(objects, images, size, None, None,
                                                            flags=INTRINSIC_FLAGS)
    except cv2.error as exc:
        raise GeometryCalibrationError(f"the camera's intrinsics could not be solved ({exc.msg}); add board "
                                       "views at more varied angles") from None
    entry = IntrinsicsEntry(width_px=size[0], height_px=size[1], matrix=matrix.tolist(),
                            distortion=distortion.ravel().tolist(), rms_px=float(rms))
    return entry, matrix, distortion.ravel()


def _check_flat(board: BoardLayout, views: list[_Seen], matrix: np.ndarray, distortion: np.ndarray) -> None:
    """Each board view's pose by solvePnP: a view whose corners no flat board's pose explains is rejected."""
    points = board.board_points()
    for s in views:
        assert s.ids is not None and s.points_px is not None
        ok, rvec, tvec = cv2.solvePnP(points[s.ids], s.points_px, matrix, distortion)
        if not ok:
            s.rejected = "solvePnP found no pose for its corners"
            continue
        projected, _ = cv2.projectPoints(points[s.ids], rvec, tvec, matrix, distortion)
        rms = float(np.sqrt(np.mean((projected.reshape(-1, 2) - s.points_px) ** 2)))
        if rms > PNP_REJECT_PX:
            s.rejected = f"its corners fit a flat board's pose to {rms:.3g} px RMS only (mis-detected corners?)"
