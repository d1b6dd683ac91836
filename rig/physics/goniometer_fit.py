"""The goniometer model of `rig calibrate geometry` and its fit to what the camera saw (docs/geometry-calibration.md).

Pure numpy/scipy. The model is the kinematics of docs/geometry.md with the errors a real goniometer has:

    F      = sample_frame(α + δα, β + δβ) · R(τx, τy, 0)            the holder's face, tilted by τ
    X      = F · (p + o)                                           a board point p (sample coordinates), the
                                                                   board's centre off the holder's by o
    C      = camera_frame(a + δa, b + δb) · R(0, 0, ρ)              the camera's roll ρ on its mount
    c      = D · camera_unit(a + δa, b + δb)
    pixel  = OpenCV projection (fx, fy, cx, cy, k1) of diag(1, −1, −1) · Cᵀ (X − c)

with α, β, a, b the encoder readings. Board views (chessboard corners) fix everything but a rotation of the whole
rig about the vertical, which changes nothing the camera sees of the board: the lamp views fix it, the camera
opposite the lamp and looking at its exit, whose centre (0, −d, 0) is projected alike. The fit is a weighted
least-squares bundle over all corners and lamp centroids, each group weighted by its own residual scatter, with the
camera's intrinsics (started from cv2.calibrateCamera's) among its parameters so that their uncertainty is carried;
its covariance, scaled by that scatter, gives the parameters' standard uncertainties. The camera's pointing is
its principal point (the pixel on its optical axis through the goniometer's centre), which a rotation of the
camera on its mount cannot be told from in a long lens's narrow field: the mount keeps only its roll.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from rig.physics.geometry import camera_frame, camera_unit, rotation_matrix, sample_frame

#: The fitted parameters, in the order of `GoniometerFit.values`; angles in degrees, lengths in metres, the
#: intrinsics in pixels (the camera's pointing is where it sees the goniometer's centre: `centre_x_px`,
#: `centre_y_px`, against the sensor's centre; k1 is OpenCV's first radial distortion coefficient).
PARAMETERS = ("stage_vertical_zero_deg", "stage_normal_zero_deg", "arm_azimuth_zero_deg", "arm_polar_zero_deg",
              "tilt_x_deg", "tilt_y_deg", "roll_deg", "camera_distance_m", "board_x_m", "board_y_m", "board_z_m",
              "focal_x_px", "focal_y_px", "centre_x_px", "centre_y_px", "k1")
ANGLES = slice(0, 7)
#: Typical size of a parameter (rad, m, px, 1): the columns of the Jacobian are compared at this scale.
SCALE = np.array([1e-3] * 7 + [1e-3] * 4 + [1.0] * 4 + [1e-2])
#: OpenCV's camera frame (x right, y down, z ahead) from rig's sensor frame (x right, y up, backward).
TO_OPENCV = np.diag([1.0, -1.0, -1.0])
#: A smallest singular value of the scaled Jacobian below this fraction of the largest: a degenerate pose set.
DEGENERATE = 1e-6
#: A view is rejected when its residual RMS exceeds this multiple of the median view's (and REJECT_FLOOR_PX).
REJECT_FACTOR = 5.0
REJECT_FLOOR_PX = 0.5
#: A fit that has not converged after this many evaluations of the model will not (a handful of iterations do).
MAX_EVALUATIONS = 40 * (len(PARAMETERS) + 1)
#: The lamp centroids' scatter is taken as at least this (px), so that a few lucky ones do not outweigh the rest.
LAMP_SIGMA_FLOOR_PX = 0.02


class FitError(ValueError):
    """The fit cannot give a result; the message says what to change."""


@dataclass(frozen=True)
class BoardView:
    """The chessboard corners `ids` seen at `image_px` (OpenCV pixel coordinates) with the axes at `motors_deg`."""

    label: str
    motors_deg: tuple[float, float, float, float]
    ids: np.ndarray
    image_px: np.ndarray


@dataclass(frozen=True)
class LampView:
    """The centroid of the lamp's exit in the image with the axes at `motors_deg`."""

    label: str
    motors_deg: tuple[float, float, float, float]
    centroid_px: np.ndarray


@dataclass(frozen=True)
class Camera:
    """Intrinsics (3×3) and OpenCV distortion coefficients (k1, k2, p1, p2[, k3])."""

    matrix: np.ndarray
    distortion: np.ndarray


@dataclass
class GoniometerFit:
    """Values (PARAMETERS' units), covariance, the groups' residual scatter and each view's residual RMS (px)."""

    values: np.ndarray
    covariance: np.ndarray
    corner_sigma_px: float
    lamp_sigma_px: float
    view_rms_px: dict[str, float]
    rejected: dict[str, str] = field(default_factory=dict)

    @property
    def u(self) -> np.ndarray:
        return np.sqrt(np.diag(self.covariance))

    def named(self) -> dict[str, tuple[float, float]]:
        return {name: (float(v), float(u)) for name, v, u in zip(PARAMETERS, self.values, self.u)}


def rotation_from_vector(vector: np.ndarray) -> np.ndarray:
    """The rotation by |v| (rad) about v; the identity, exactly, for v = 0."""
    angle = float(np.linalg.norm(vector))
    return np.eye(3) if angle == 0.0 else rotation_matrix(vector / angle, angle)


def _internal(values: np.ndarray) -> np.ndarray:
    """PARAMETERS' units → radians and metres."""
    p = np.asarray(values, float).copy()
    p[ANGLES] = np.radians(p[ANGLES])
    return p


def camera_points(values: np.ndarray, motors_deg: np.ndarray, sample_points: np.ndarray) -> np.ndarray:
    """Board points (M, 3, sample coordinates) in OpenCV's camera frame for each view's axes (N, 4): (N, M, 3)."""
    p = _internal(values)
    m = np.radians(np.atleast_2d(np.asarray(motors_deg, float))) + p[:4]
    frame = sample_frame(m[:, 0], m[:, 1]) @ rotation_from_vector(np.array([p[4], p[5], 0.0]))
    world = (np.asarray(sample_points, float) + p[8:11]) @ np.swapaxes(frame, 1, 2)            # (N, M, 3)
    return _to_camera(p, m, world)


def _to_camera(p: np.ndarray, m: np.ndarray, world: np.ndarray) -> np.ndarray:
    """GCS points (N, M, 3) in OpenCV's camera frame, the arm at the true angles m (N, 4; rad)."""
    cam = camera_frame(m[:, 2], m[:, 3]) @ rotation_from_vector(np.array([0.0, 0.0, p[6]]))
    centre = p[7] * camera_unit(m[:, 2], m[:, 3])
    return (world - centre[:, None, :]) @ (cam @ TO_OPENCV)                                 # (Cᵀ)ᵀ = C


def intrinsics(values: np.ndarray) -> Camera:
    """The camera's matrix and distortion of a parameter vector."""
    fx, fy, cx, cy, k1 = np.asarray(values, float)[11:16]
    return Camera(np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]]), np.array([k1, 0.0, 0.0, 0.0, 0.0]))


def start_values(camera: Camera, camera_distance_m: float) -> np.ndarray:
    """The nominal rig (no zero offsets, tilt, roll or board offset) seen through `camera` (its k1 only)."""
    k = camera.matrix
    values = np.zeros(len(PARAMETERS))
    values[7] = camera_distance_m
    values[11:16] = k[0, 0], k[1, 1], k[0, 2], k[1, 2], float(np.ravel(camera.distortion)[0])
    return values


def project(points: np.ndarray, camera: Camera) -> np.ndarray:
    """OpenCV's pinhole projection with radial and tangential distortion of camera-frame points (..., 3)."""
    x, y = points[..., 0] / points[..., 2], points[..., 1] / points[..., 2]
    d = np.zeros(5)
    d[:min(5, camera.distortion.size)] = camera.distortion.ravel()[:5]
    r2 = x * x + y * y
    radial = 1 + d[0] * r2 + d[1] * r2 ** 2 + d[4] * r2 ** 3
    xd = x * radial + 2 * d[2] * x * y + d[3] * (r2 + 2 * x * x)
    yd = y * radial + d[2] * (r2 + 2 * y * y) + 2 * d[3] * x * y
    k = camera.matrix
    return np.stack([k[0, 0] * xd + k[0, 1] * yd + k[0, 2], k[1, 1] * yd + k[1, 2]], axis=-1)


def predict_lamp(values: np.ndarray, motors_deg: np.ndarray, lamp_distance_m: float) -> np.ndarray:
    """Where the lamp exit's centre (0, −d, 0) appears (N, 2) for each view's axes (N, 4)."""
    p = _internal(values)
    m = np.radians(np.atleast_2d(np.asarray(motors_deg, float))) + p[:4]
    lamp = np.broadcast_to([0.0, -lamp_distance_m, 0.0], (len(m), 1, 3))
    return project(_to_camera(p, m, lamp), intrinsics(values))[:, 0]


class _Problem:
    """The views as flat arrays, and the weighted residuals of a parameter vector."""

    def __init__(self, boards: list[BoardView], lamps: list[LampView], sample_points: np.ndarray,
                 lamp_distance_m: float):
        self.boards, self.lamps, self.points = boards, lamps, sample_points
        self.lamp_distance_m = lamp_distance_m
        self.board_motors = np.array([v.motors_deg for v in boards], float).reshape(-1, 4)
        self.lamp_motors = np.array([v.motors_deg for v in lamps], float).reshape(-1, 4)
        self.view = np.concatenate([np.full(len(v.ids), i) for i, v in enumerate(boards)]).astype(int)
        self.corner = np.concatenate([np.asarray(v.ids, int).ravel() for v in boards])
        self.seen = np.concatenate([np.asarray(v.image_px, float).reshape(-1, 2) for v in boards])
        self.lamp_seen = np.array([v.centroid_px for v in lamps], float).reshape(-1, 2)

    def corner_residuals(self, values: np.ndarray) -> np.ndarray:
        predicted = project(camera_points(values, self.board_motors, self.points), intrinsics(values))
        return predicted[self.view, self.corner] - self.seen

    def lamp_residuals(self, values: np.ndarray) -> np.ndarray:
        if not self.lamps:
            return np.empty((0, 2))
        return predict_lamp(values, self.lamp_motors, self.lamp_distance_m) - self.lamp_seen

    def weighted(self, values: np.ndarray, sigmas: tuple[float, float]) -> np.ndarray:
        return np.concatenate([self.corner_residuals(values).ravel() / sigmas[0],
                               self.lamp_residuals(values).ravel() / sigmas[1]])


def fit(boards: list[BoardView], lamps: list[LampView], sample_points: np.ndarray, camera: Camera, *,
        camera_distance_m: float, lamp_distance_m: float) -> GoniometerFit:
    """Fit the model to the views, starting from the nominal rig seen through `camera` (cv2.calibrateCamera's),
    rejecting views whose residuals stand out (GoniometerFit.rejected says why); FitError naming what to change
    when the views cannot determine it."""
    rejected: dict[str, str] = {}
    start = start_values(camera, camera_distance_m)
    while True:
        problem = _Problem(boards, lamps, sample_points, lamp_distance_m)
        values, sigmas = _solve(problem, start)
        rms = _view_rms(problem, values)
        typical = float(np.median(list(rms.values())))
        worst = max(rms, key=lambda k: rms[k])
        if rms[worst] <= max(REJECT_FACTOR * typical, REJECT_FLOOR_PX):
            break
        rejected[worst] = (f"residual RMS {rms[worst]:.3g} px, over {REJECT_FACTOR:g}× the median view's "
                           f"{typical:.3g} px (a pose the model does not explain: a slipped board, a mis-detection)")
        boards = [v for v in boards if v.label != worst]
        lamps = [v for v in lamps if v.label != worst]
        start = values
        try:
            _check_counts(boards, lamps)
        except FitError as exc:
            raise FitError(f"{', '.join(rejected)} rejected ({rejected[worst]}); {exc}") from None
    covariance = _covariance(problem, values, sigmas)
    return GoniometerFit(values, covariance, sigmas[0], sigmas[1], rms, rejected)


def _covariance(problem: _Problem, values: np.ndarray, sigmas: tuple[float, float]) -> np.ndarray:
    """The parameters' covariance (PARAMETERS' units): the least-squares one, each u raised to the cluster-robust
    one's (views as clusters: a view's corners share its errors — a slightly wrong exposure of its edges, the
    board's sag — which the per-corner scatter does not show), with the cluster-robust correlations."""
    jac = _jacobian(problem, values, sigmas)                # per PARAMETERS' unit already
    bread = np.linalg.inv(jac.T @ jac)
    residuals = problem.weighted(values, sigmas)
    lamp_clusters = len(problem.boards) + np.repeat(np.arange(len(problem.lamps)), 2)
    clusters = np.concatenate([np.repeat(problem.view, 2), lamp_clusters])
    scores = np.stack([jac[clusters == c].T @ residuals[clusters == c] for c in np.unique(clusters)])
    n = len(scores)
    robust = bread @ (scores.T @ scores) @ bread * n / (n - 1)
    u_robust = np.sqrt(np.diag(robust))
    u = np.maximum(np.sqrt(np.diag(bread)), u_robust)
    return robust / np.outer(u_robust, u_robust) * np.outer(u, u)


def _check_counts(boards: list[BoardView], lamps: list[LampView]) -> None:
    if len(boards) < 6:
        raise FitError(f"{len(boards)} board views left, at least 6 are needed: add poses where the board is seen")
    if len(lamps) < 2:
        raise FitError(f"{len(lamps)} lamp views left, at least 2 are needed: without them the rotation of the "
                       "whole rig about the vertical is not seen; add poses with the camera opposite the lamp")


def _solve(problem: _Problem, start: np.ndarray) -> tuple[np.ndarray, tuple[float, float]]:
    """Least squares, twice: with nominal weights, then with each group's own scatter."""
    from scipy.optimize import least_squares  # here: rig files name this module's PARAMETERS, and load fast

    _check_counts(problem.boards, problem.lamps)
    sigmas = (0.1, 0.05)
    values = start
    for _ in range(2):
        _check_degenerate(_jacobian(problem, values, sigmas))
        result = least_squares(problem.weighted, values, args=(sigmas,), x_scale=_scale(values), method="lm",
                               xtol=1e-12, ftol=1e-12, max_nfev=MAX_EVALUATIONS)
        if not result.success:
            raise FitError(f"the fit did not converge ({result.message}); check that the rig file's camera and "
                           "lamp distances are near the truth and the board lies with its rows along the sample x")
        values = result.x
        corners, lamp = problem.corner_residuals(values), problem.lamp_residuals(values)
        dof = max(corners.size - len(PARAMETERS), 1)
        sigmas = (float(np.sqrt(np.sum(corners ** 2) / dof)),
                  max(float(np.sqrt(np.sum(lamp ** 2) / max(lamp.size - 2, 1))), LAMP_SIGMA_FLOOR_PX))
    if sigmas[0] > 2.0:
        raise FitError(f"the fit left corner residuals of {sigmas[0]:.3g} px RMS: the model does not explain the "
                       "views; check the board layout (--board), that it lies flat on the holder, and the axes")
    return values, sigmas


def _scale(values: np.ndarray) -> np.ndarray:
    """least_squares' x_scale: SCALE in PARAMETERS' units."""
    scale = SCALE.copy()
    scale[ANGLES] = np.degrees(scale[ANGLES])
    return scale


def _jacobian(problem: _Problem, values: np.ndarray, sigmas: tuple[float, float]) -> np.ndarray:
    """Central differences of the weighted residuals, per parameter, in PARAMETERS' units."""
    step = _scale(values) * 1e-3
    columns = []
    for k, h in enumerate(step):
        dv = np.zeros_like(values)
        dv[k] = h
        columns.append((problem.weighted(values + dv, sigmas) - problem.weighted(values - dv, sigmas)) / (2 * h))
    return np.stack(columns, axis=1)


def _check_degenerate(jac: np.ndarray) -> None:
    """FitError naming the parameters the views cannot tell apart (the scaled Jacobian's near-null direction)."""
    scaled = jac * _scale(np.zeros(len(PARAMETERS)))
    eigenvalues, vectors = np.linalg.eigh(scaled.T @ scaled)           # the squared singular values, ascending
    if eigenvalues[0] >= DEGENERATE ** 2 * eigenvalues[-1]:
        return
    null = vectors[:, 0] / np.max(np.abs(vectors[:, 0]))
    names = [name for name, w in zip(PARAMETERS, null) if abs(w) > 0.2]
    raise FitError(f"degenerate pose set: the views cannot tell {', '.join(names)} apart; add poses that "
                   "turn the stage and arm over wider ranges of all four axes (docs/geometry-calibration.md)")


def _view_rms(problem: _Problem, values: np.ndarray) -> dict[str, float]:
    corners, lamp = problem.corner_residuals(values), problem.lamp_residuals(values)
    rms = {v.label: float(np.sqrt(np.mean(corners[problem.view == i] ** 2))) for i, v in enumerate(problem.boards)}
    rms.update({v.label: float(np.sqrt(np.mean(lamp[i] ** 2))) for i, v in enumerate(problem.lamps)})
    return rms


def pointing_deg(values: np.ndarray, covariance: np.ndarray, width_px: int,
                 height_px: int) -> tuple[tuple[float, float], tuple[float, float]]:
    """How far the camera looks past the goniometer's centre, along the image's columns and rows (deg), each with
    its standard uncertainty: the principal point against the sensor's centre, (c − size/2 + ½) / f (OpenCV's
    pixel centres are integers), through the covariance of (f, c)."""
    out = []
    for f_index, c_index, size in ((11, 13, width_px), (12, 14, height_px)):
        f, c = values[f_index], values[c_index]
        offset = c - (size - 1) / 2
        gradient = np.array([-offset / (f * f + offset * offset), f / (f * f + offset * offset)])   # d atan(o/f)
        block = covariance[np.ix_([f_index, c_index], [f_index, c_index])]
        out.append((float(np.degrees(np.arctan2(offset, f))), float(np.degrees(np.sqrt(gradient @ block @ gradient)))))
    return out[0], out[1]


def calibration_poses(board_views: int = 18, lamp_views: int = 5) -> tuple[list[tuple[float, float, float, float]],
                                                                           list[tuple[float, float, float, float]]]:
    """The axes (stage_vertical, stage_normal, arm_azimuth, arm_polar; deg) of the board views and the lamp views.

    Board views: the stage turned ±20° about the vertical, the board turned about its normal in steps of 75° (each
    view sees it turned anew), the camera 20° or 45° above the board's normal and 45° to either side of it: 48°
    to 60° from the normal, oblique enough to tell the board's turn about its normal from the camera's roll about
    its axis, and each axis moving independently of the others. Lamp views: the camera opposite the lamp
    (a = b = 90°, looking along −Y into the lamp's exit) and 2° off it on either arm axis."""
    grid = [(v, v - 90.0 + side, 90.0 - up) for up in (20.0, 45.0) for side in (-45.0, 45.0) for v in (-20.0, 20.0)]
    boards = [(v, float((75 * i) % 360 - 180), a, b) for i, (v, a, b) in
              enumerate(grid[k % len(grid)] for k in range(board_views))]
    offsets = [(0.0, 0.0), (2.0, 0.0), (-2.0, 0.0), (0.0, 2.0), (0.0, -2.0)]
    lamps = [(0.0, 0.0, 90.0 + da, 90.0 + db) for da, db in (offsets * lamp_views)[:lamp_views]]
    return boards, lamps
