"""Angle conventions and goniometer kinematics (contract: docs/geometry.md).

Pure, vectorised numpy. Radians inside; functions whose names end in `_deg`
take and return degrees and are the only ones the rest of the application
uses at its edges.

Frames: the sample coordinate system (SCS) has z = outward sample normal; the
global coordinate system (GCS) has its origin at the goniometer centre, Z up,
and the lamp beam travelling along +Y, so the incident direction (pointing away
from the sample, toward the lamp) is (0, -1, 0) in the GCS.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

TWO_PI = 2.0 * np.pi
#: Direction toward the lamp in the GCS.
LAMP_DIRECTION_GCS = np.array([0.0, -1.0, 0.0])
#: Columns: sample x, y, n at home (all axes zero), in the GCS.
M0 = np.array([[1.0, 0.0, 0.0],
               [0.0, 0.0, -1.0],
               [0.0, 1.0, 0.0]])
N_HOME = M0[:, 2]
#: Below this sin(polar angle) the azimuth is treated as undefined (a pole).
POLE_EPS = 1e-12
#: Motion costs (radians) closer than this count as equal when choosing an arm branch.
_TIE_RAD = 1e-12


def sph_to_vec(theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Unit vectors (..., 3) from polar angle θ (from z) and azimuth φ, radians."""
    theta, phi = np.broadcast_arrays(np.asarray(theta, float), np.asarray(phi, float))
    st = np.sin(theta)
    return np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta)], axis=-1)


def vec_to_sph(v: np.ndarray, phi_at_pole: np.ndarray | float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """(θ, φ) in radians of vectors (..., 3); φ wrapped to [0, 2π).

    At the poles φ is undefined: `phi_at_pole` (e.g. the requested azimuth) is
    returned there so writers always emit a finite value.
    """
    v = np.asarray(v, float)
    rho = np.hypot(v[..., 0], v[..., 1])
    theta = np.arctan2(rho, v[..., 2])
    phi = wrap_2pi(np.arctan2(v[..., 1], v[..., 0]))
    phi = np.where(_at_pole(v), wrap_2pi(np.broadcast_to(phi_at_pole, phi.shape)), phi)
    return theta, phi


def _at_pole(v: np.ndarray) -> np.ndarray:
    """True where the azimuth of the vectors (..., 3) is undefined (on the z axis)."""
    rho = np.hypot(v[..., 0], v[..., 1])
    return rho <= POLE_EPS * np.maximum(np.abs(v[..., 2]), 1.0)


def wrap_2pi(angle: ArrayLike) -> np.ndarray:
    """Wrap to [0, 2π), mapping values that round to 2π onto 0."""
    w = np.mod(angle, TWO_PI)
    return np.where(w >= TWO_PI, 0.0, w)


def wrap_360(angle_deg: ArrayLike) -> np.ndarray:
    """Wrap degrees to [0, 360), mapping values that round to 360 onto 0 (never 360.0)."""
    w = np.mod(np.asarray(angle_deg, float), 360.0)
    return np.where(w >= 360.0, 0.0, w)


def wrap_pi(angle: ArrayLike) -> np.ndarray:
    """Wrap to [-π, π)."""
    return wrap_2pi(np.asarray(angle, float) + np.pi) - np.pi


def mean_direction_deg(theta_deg: ArrayLike, phi_deg: ArrayLike) -> tuple[float, float]:
    """(θ, φ) in degrees (φ in [0, 360)) of the mean of some directions' unit vectors: an average that
    does not break where φ wraps or at the pole."""
    v = sph_to_vec(np.radians(np.asarray(theta_deg, float)), np.radians(np.asarray(phi_deg, float)))
    theta, phi = vec_to_sph(v.reshape(-1, 3).mean(axis=0))
    return float(np.degrees(theta)), float(wrap_360(np.degrees(phi)))


_EYE3 = np.eye(3)
#: Row k: the cross-product matrix [eₖ]× of the k-th unit vector, flattened, so that k @ this is [k]×.
_CROSS_BY_AXIS = np.array([[0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 1.0, 0.0],
                           [0.0, 0.0, 1.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0],
                           [0.0, -1.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]])


def dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Dot products along the last axis, broadcasting the others (einsum: no big temporaries)."""
    return np.einsum("...i,...i->...", u, v)


def angle_between(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Angle between vectors (..., 3) in radians; accurate near 0 and π (atan2 form)."""
    cross = np.linalg.norm(np.cross(u, v), axis=-1)
    return np.arctan2(cross, dot(u, v))


def rotation_matrix(axis: ArrayLike, angle: ArrayLike) -> np.ndarray:
    """Right-handed rotation(s) about unit `axis` (..., 3) by `angle` (...), Rodrigues:
    R = cos θ·I + sin θ·[k]× + (1 − cos θ)·k kᵀ, in a few whole-array operations (the rig builds
    single matrices thousands of times a run, so per-call overhead counts as much as the arithmetic)."""
    unit = np.asarray(axis, float)
    turn = np.asarray(angle, float)[..., None, None]
    c, s = np.cos(turn), np.sin(turn)
    cross = (unit @ _CROSS_BY_AXIS).reshape(unit.shape[:-1] + (3, 3))            # [k]×
    return c * _EYE3 + s * cross + (1.0 - c) * (unit[..., :, None] * unit[..., None, :])


def rot_z(angle: ArrayLike) -> np.ndarray:
    return rotation_matrix(np.array([0.0, 0.0, 1.0]), angle)


def rot_y(angle: ArrayLike) -> np.ndarray:
    return rotation_matrix(np.array([0.0, 1.0, 0.0]), angle)


def sample_frame(alpha: ArrayLike, beta: ArrayLike) -> np.ndarray:
    """F = Rz(α)·R_n_home(β)·M0: columns are the sample x, y, n in the GCS (..., 3, 3)."""
    return rot_z(alpha) @ rotation_matrix(N_HOME, beta) @ M0


def camera_unit(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """Unit vector from the origin to the camera, Rz(a)·Ry(b)·(0, 0, 1), in the GCS."""
    az, polar = np.broadcast_arrays(np.asarray(a, float), np.asarray(b, float))
    sb = np.sin(polar)
    return np.stack([np.cos(az) * sb, np.sin(az) * sb, np.cos(polar)], axis=-1)


def camera_frame(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """Rz(a)·Ry(b): columns are the sensor x, sensor y and the camera's backward axis (GCS).

    At home the camera sits on +Z looking down, sensor x = GCS X, sensor y = GCS Y.
    """
    return rot_z(a) @ rot_y(b)


def directions_scs(alpha: ArrayLike, beta: ArrayLike, a: ArrayLike, b: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
    """Forward kinematics: (ωi, ωo) as SCS unit vectors for motor angles in radians."""
    frame = sample_frame(alpha, beta)
    frame_t = np.swapaxes(frame, -1, -2)
    wi = frame_t @ LAMP_DIRECTION_GCS
    wo = np.einsum("...ij,...j->...i", frame_t, camera_unit(a, b))
    return wi, wo


@dataclass(frozen=True)
class BrdfAngles:
    """BRDF angles (degrees, φ in [0, 360))."""

    theta_i_deg: np.ndarray
    phi_i_deg: np.ndarray
    theta_o_deg: np.ndarray
    phi_o_deg: np.ndarray


@dataclass(frozen=True)
class MotorAngles:
    """Axis positions (degrees); NaN where no solution lies inside the limits."""

    stage_vertical_deg: np.ndarray
    stage_normal_deg: np.ndarray
    arm_azimuth_deg: np.ndarray
    arm_polar_deg: np.ndarray

    def as_array(self) -> np.ndarray:
        """(..., 4) in the order stage_vertical, stage_normal, arm_azimuth, arm_polar."""
        return np.stack([self.stage_vertical_deg, self.stage_normal_deg,
                         self.arm_azimuth_deg, self.arm_polar_deg], axis=-1)


AXIS_NAMES = ("stage_vertical", "stage_normal", "arm_azimuth", "arm_polar")


def forward_deg(stage_vertical_deg, stage_normal_deg, arm_azimuth_deg, arm_polar_deg,
                phi_i_at_pole_deg=0.0, phi_o_at_pole_deg=0.0) -> BrdfAngles:
    """Motor angles → achieved BRDF angles, degrees. Azimuths at a pole keep the given values.

    All arguments broadcast together. At a pole (θ = 0, or 180) the given azimuth is
    returned exactly (only wrapped to [0, 360)), without a trip through radians.
    """
    args = np.broadcast_arrays(*(np.asarray(x, float) for x in (
        stage_vertical_deg, stage_normal_deg, arm_azimuth_deg, arm_polar_deg,
        phi_i_at_pole_deg, phi_o_at_pole_deg)))
    wi, wo = directions_scs(*(np.radians(x) for x in args[:4]))
    out = []
    for v, phi_pole_deg in ((wi, args[4]), (wo, args[5])):
        theta, phi = vec_to_sph(v)
        phi_deg = np.where(_at_pole(v), wrap_360(phi_pole_deg), wrap_360(np.degrees(phi)))
        out += [np.degrees(theta), phi_deg]
    return BrdfAngles(*(x[()] for x in out))


def _nearest_in_limits(angle: np.ndarray, current: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """The representative angle + 2πk inside [lo, hi] nearest `current`; NaN if none.

    The distance to `current` is convex in k, so clipping the unconstrained best
    k into the admissible range gives the constrained optimum.
    """
    tol = 1e-12
    k_min = np.ceil((lo - angle) / TWO_PI - tol)
    k_max = np.floor((hi - angle) / TWO_PI + tol)
    k = np.clip(np.round((current - angle) / TWO_PI), k_min, k_max)
    best = np.clip(angle + k * TWO_PI, lo, hi)
    return np.where(k_min <= k_max, best, np.nan)


@dataclass(frozen=True)
class AxisLimits:
    """Soft limits of the four axes, degrees (inclusive)."""

    stage_vertical: tuple[float, float] = (-90.0, 90.0)
    stage_normal: tuple[float, float] = (-360.0, 360.0)
    arm_azimuth: tuple[float, float] = (-180.0, 180.0)
    arm_polar: tuple[float, float] = (-180.0, 180.0)


def inverse_deg(theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg,
                limits: AxisLimits = AxisLimits(),
                current_deg: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)) -> MotorAngles:
    """BRDF angles → motor angles (degrees), vectorised.

    The stage uses α = -θi, β = -φi (shifted by whole turns to the representative
    inside the limits nearest the current position). Of the two arm solutions
    (a, b) and (a + 180°, -b) the one inside the limits nearest the current
    position (least |Δa| + |Δb|, each at its representative inside the limits
    nearest the current position; the b ≥ 0 branch on a tie) wins; at the poles
    (b = 0 or 180°) the azimuth is free and the current one is kept (clipped into
    the limits). Results never lie outside the limits. Unreachable entries are NaN
    in every axis.
    """
    ti, pi_, to, po = (np.radians(np.asarray(x, float)) for x in
                       (theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg))
    ti, pi_, to, po = np.broadcast_arrays(ti, pi_, to, po)
    lim = {k: np.radians(getattr(limits, k)) for k in AXIS_NAMES}
    cur = dict(zip(AXIS_NAMES, np.radians(np.asarray(current_deg, float))))

    alpha = _nearest_in_limits(-ti, cur["stage_vertical"], *lim["stage_vertical"])
    beta = _nearest_in_limits(-pi_, cur["stage_normal"], *lim["stage_normal"])
    frame = sample_frame(np.nan_to_num(alpha), np.nan_to_num(beta))
    c = np.einsum("...ij,...j->...i", frame, sph_to_vec(to, po))
    rho = np.hypot(c[..., 0], c[..., 1])
    b_pos = np.arctan2(rho, c[..., 2])                       # in [0, π]
    at_pole = rho <= POLE_EPS
    a_pos = np.arctan2(c[..., 1], c[..., 0])
    # At the pole the azimuth is free: keep the current one (moved into the limits).
    a_free = np.clip(cur["arm_azimuth"], *lim["arm_azimuth"])

    best_a = np.full(ti.shape, np.nan)
    best_b = np.full(ti.shape, np.nan)
    best_cost = np.full(ti.shape, np.inf)
    for a_cand, b_cand in ((a_pos, b_pos), (a_pos + np.pi, -b_pos)):
        a_rep = _nearest_in_limits(a_cand, cur["arm_azimuth"], *lim["arm_azimuth"])
        a_rep = np.where(at_pole, a_free, a_rep)
        # b is an angle too: any representative b + 2πk inside the limits will do
        b_rep = _nearest_in_limits(b_cand, cur["arm_polar"], *lim["arm_polar"])
        cost = np.abs(a_rep - cur["arm_azimuth"]) + np.abs(b_rep - cur["arm_polar"])
        # the second branch must be better by more than round-off, so that the
        # choice between equidistant twins is deterministic (the first, b >= 0)
        take = np.isfinite(cost) & (cost < best_cost - _TIE_RAD)
        best_a = np.where(take, a_rep, best_a)
        best_b = np.where(take, b_rep, best_b)
        best_cost = np.where(take, cost, best_cost)

    bad = ~(np.isfinite(alpha) & np.isfinite(beta) & np.isfinite(best_a))
    # clip in degrees as well: radians → degrees may overshoot a limit by an ulp
    out = [np.where(bad, np.nan, np.clip(np.degrees(x), *getattr(limits, name)))
           for x, name in zip((alpha, beta, best_a, best_b), AXIS_NAMES)]
    return MotorAngles(*out)


def centre_pattern(theta: np.ndarray, phi: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Rotate pattern directions sph(θ, φ) by the minimal rotation taking z to `centre`.

    theta, phi: radians, shape (M,); centre: unit vector (3,). Returns (M, 3).
    Identity when the centre is z; a half turn about x when it is -z.
    """
    d = sph_to_vec(theta, phi)
    centre = np.asarray(centre, float) / np.linalg.norm(centre)
    z = np.array([0.0, 0.0, 1.0])
    axis = np.cross(z, centre)
    s = np.linalg.norm(axis)
    if s <= 1e-15:
        return d if centre[2] > 0 else d @ rotation_matrix(np.array([1.0, 0.0, 0.0]), np.pi).T
    rot = rotation_matrix(axis / s, np.arctan2(s, centre[2]))
    return d @ rot.T


def mirror_direction(w: np.ndarray) -> np.ndarray:
    """Specular direction of w about the normal z: (θ, φ + 180°)."""
    return np.asarray(w, float) * np.array([-1.0, -1.0, 1.0])


def disk_coordinates(theta_o_deg: np.ndarray, phi_o_deg: np.ndarray, phi_i_deg: np.ndarray | float) -> np.ndarray:
    """(..., 2): the view in the projected (Nusselt) disk relative to the incidence plane, folded to |sin Δφ|:
    the coordinates in which an isotropic sample's views are interpolated and spread."""
    t, dphi = np.radians(theta_o_deg), np.radians(np.asarray(phi_o_deg) - np.asarray(phi_i_deg))
    s = np.sin(t)
    return np.stack([s * np.cos(dphi), s * np.abs(np.sin(dphi))], axis=-1)


#: Views within this angle (degrees) of the plane of incidence are drawn in the plane plots.
PLANE_TOL_DEG = 2.0
#: Below this θi (degrees) the plane of incidence is undefined; the x–z plane is used.
NORMAL_INCIDENCE_DEG = 1.0


def plane_axes(theta_i_deg: float, phi_i_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """(t, n): unit vector in the plane of incidence toward the lamp's azimuth, and the plane's normal."""
    phi = np.radians(phi_i_deg) if theta_i_deg >= NORMAL_INCIDENCE_DEG else 0.0
    return np.array([np.cos(phi), np.sin(phi), 0.0]), np.array([-np.sin(phi), np.cos(phi), 0.0])


def plane_offsets(wo: np.ndarray, t: np.ndarray, n: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Angular distance of views from the plane, and their signed angle in it (deg, + toward the lamp)."""
    off = np.degrees(np.arcsin(np.clip(np.abs(wo @ n), 0.0, 1.0)))
    return off, np.degrees(np.arctan2(wo @ t, wo[:, 2]))
