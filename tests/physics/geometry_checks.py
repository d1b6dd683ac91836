"""Tolerances, independent reference kinematics and round-trip checks shared by tests/physics/test_geometry.py,
test_kinematics.py and test_arm_branches.py (the tolerances are explained at the top of test_geometry.py)."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

from rig.physics.geometry import (
    AXIS_NAMES,
    AxisLimits,
    MotorAngles,
    angle_between,
    forward_deg,
    sph_to_vec,
)

TOL_DEG = 1e-9          # the contract's round-trip accuracy
PHI_THETA_MIN_DEG = 0.1  # below this θ, φ is checked through the direction only (test_geometry.py, top)
RNG_SEED = 20230417


# --------------------------------------------------------------------------- helpers
def circ_diff_deg(a, b):
    """|a - b| on the circle, degrees, in [0, 180]."""
    return np.abs((np.asarray(a, float) - np.asarray(b, float) + 180.0) % 360.0 - 180.0)


def vec_deg(theta_deg, phi_deg):
    return sph_to_vec(np.radians(theta_deg), np.radians(phi_deg))


def angle_deg(u, v):
    return np.degrees(angle_between(u, v))


def ref_sample_frame(alpha_deg, beta_deg):
    """Independent implementation of F = Rz(α)·R_n_home(β)·M0 with scipy (vectorised)."""
    m0 = np.column_stack([(1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (0.0, -1.0, 0.0)])
    alpha_deg, beta_deg = np.broadcast_arrays(np.asarray(alpha_deg, float), np.asarray(beta_deg, float))
    rz = Rotation.from_rotvec(np.radians(alpha_deg.ravel())[:, None] * [0.0, 0.0, 1.0]).as_matrix()
    rn = Rotation.from_rotvec(np.radians(beta_deg.ravel())[:, None] * [0.0, -1.0, 0.0]).as_matrix()
    return (rz @ rn @ m0).reshape(alpha_deg.shape + (3, 3))


def ref_directions(alpha_deg, beta_deg, a_deg, b_deg):
    """Independent forward kinematics straight from the contract (one pose)."""
    f = ref_sample_frame(alpha_deg, beta_deg)
    rz = Rotation.from_rotvec(np.radians(a_deg) * np.array([0.0, 0.0, 1.0])).as_matrix()
    ry = Rotation.from_rotvec(np.radians(b_deg) * np.array([0.0, 1.0, 0.0])).as_matrix()
    cam = 1.54 * rz @ ry @ np.array([0.0, 0.0, 1.0])
    wi = f.T @ np.array([0.0, -1.0, 0.0])
    wo = f.T @ cam / np.linalg.norm(cam)
    return wi, wo


def random_requests(rng, n, theta_i_max=90.0, theta_o_max=90.0, specials=True):
    """Random reachable requests (degrees), with the awkward values mixed in."""
    ti = rng.uniform(0.0, theta_i_max, n)
    pi_ = rng.uniform(0.0, 360.0, n)
    to = rng.uniform(0.0, theta_o_max, n)
    po = rng.uniform(0.0, 360.0, n)
    if specials:
        k = n // 20
        special_theta_i = np.array([0.0, 1e-12, 1e-7, 0.5, 45.0, 89.999999, theta_i_max])
        special_theta_o = np.array([0.0, 1e-12, 1e-7, 0.5, 45.0, 89.999999])
        special_phi = np.array([0.0, 1e-12, 0.0001, 90.0, 180.0, 270.0, 359.9999,
                                360.0 - 1e-10, 360.0])
        ti[:k] = rng.choice(special_theta_i, k)
        to[k:2 * k] = rng.choice(special_theta_o, k)
        pi_[2 * k:3 * k] = rng.choice(special_phi, k)
        po[3 * k:4 * k] = rng.choice(special_phi, k)
        ti[4 * k:5 * k] = rng.choice(special_theta_i, k)
        to[4 * k:5 * k] = rng.choice(special_theta_o, k)
    return ti, pi_, to, po


def assert_round_trip(ti, pi_, to, po, motors: MotorAngles, mask=None):
    """forward(motors) reproduces the request (see the tolerance notes at the top)."""
    ti, pi_, to, po = np.broadcast_arrays(*(np.asarray(x, float) for x in (ti, pi_, to, po)))
    m = motors.as_array()
    if mask is None:
        mask = np.ones(ti.shape, bool)
    assert np.all(np.isfinite(m[mask])), "reachable request returned NaN"
    m = m[mask]
    ti, pi_, to, po = ti[mask], pi_[mask], to[mask], po[mask]
    got = forward_deg(*m.T, phi_i_at_pole_deg=pi_, phi_o_at_pole_deg=po)
    for th, ph, gth, gph, name in ((ti, pi_, got.theta_i_deg, got.phi_i_deg, "i"),
                                   (to, po, got.theta_o_deg, got.phi_o_deg, "o")):
        ang = angle_deg(vec_deg(th, ph), vec_deg(gth, gph))
        assert ang.max() < TOL_DEG, f"ω{name} off by {ang.max()}°"
        assert np.abs(gth - th).max() < TOL_DEG, f"θ{name} off by {np.abs(gth - th).max()}°"
        assert np.all((gph >= 0.0) & (gph < 360.0)), f"φ{name} outside [0, 360)"
        dphi = circ_diff_deg(gph, ph)
        away = th >= PHI_THETA_MIN_DEG
        assert dphi[away].max(initial=0.0) < TOL_DEG, f"φ{name} off by {dphi[away].max()}°"
        assert (dphi * np.sin(np.radians(th))).max() < TOL_DEG
        pole = th == 0.0
        assert np.all(dphi[pole] < 1e-9), f"φ{name} not kept at the pole"


def assert_within_limits(motors: MotorAngles, limits: AxisLimits):
    m = motors.as_array()
    ok = np.all(np.isfinite(m), axis=-1)
    for k, name in enumerate(AXIS_NAMES):
        lo, hi = getattr(limits, name)
        v = m[ok, k]
        assert np.all((v >= lo) & (v <= hi)), f"{name} outside [{lo}, {hi}]: {v[(v < lo) | (v > hi)][:5]}"


def arm_candidates(ti, pi_, to, po):
    """Independent arm solutions: GCS camera vector for α=-θi, β=-φi and its (a, b) branches."""
    ti, pi_, to, po = np.broadcast_arrays(*(np.atleast_1d(np.asarray(x, float)) for x in (ti, pi_, to, po)))
    c = np.einsum("...ij,...j->...i", ref_sample_frame(-ti, -pi_), vec_deg(to, po))
    rho = np.hypot(c[..., 0], c[..., 1])
    a0 = np.degrees(np.arctan2(c[..., 1], c[..., 0]))
    b0 = np.degrees(np.arctan2(rho, c[..., 2]))
    return a0, b0, rho < 1e-12


#: Reachability is decided by round-off at a limit: inverse_deg snaps within 3.6e-10° onto it, the
#: brute force here allows 1e-9°. Requests this close to a limit may come out either way.
LIMIT_TOL_DEG = 1e-9


def representatives(angle, lo, hi, turns=4, tol=LIMIT_TOL_DEG):
    """All angle + 360k inside [lo - tol, hi + tol] (list of arrays, NaN where not inside)."""
    out = []
    for k in range(-turns, turns + 1):
        v = angle + 360.0 * k
        out.append(np.where((v >= lo - tol) & (v <= hi + tol), v, np.nan))
    return np.stack(out, axis=-1)


def best_arm_cost(a0, b0, at_pole, limits: AxisLimits, cur_a, cur_b, tol=LIMIT_TOL_DEG):
    """Brute-force minimum |Δa| + |Δb| over both branches and all representatives; inf if none.

    `tol` widens the limits (a negative one narrows them: reachable without any round-off doubt)."""
    best = np.full(np.shape(a0), np.inf)
    for a_br, b_br in ((a0, b0), (a0 + 180.0, -b0)):
        a_reps = representatives(a_br, *limits.arm_azimuth, tol=tol)
        b_reps = representatives(b_br, *limits.arm_polar, tol=tol)
        cost = (np.abs(a_reps[..., :, None] - cur_a) + np.abs(b_reps[..., None, :] - cur_b))
        cost = np.where(np.isnan(cost), np.inf, cost).min(axis=(-1, -2))
        # at the arm pole the azimuth is free: keeping the current one costs nothing
        b_cost = np.where(np.isnan(b_reps), np.inf, np.abs(b_reps - cur_b)).min(axis=-1)
        pole_cost = b_cost + abs(np.clip(cur_a, *limits.arm_azimuth) - cur_a)
        best = np.minimum(best, np.where(at_pole, pole_cost, cost))
    return best
