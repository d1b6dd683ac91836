"""Inverse kinematics of rig.physics.geometry against docs/geometry.md: inverse → forward round trips, the poles,
the φ wrap (arm branches and property tests: test_arm_branches.py; tolerances: the top of test_geometry.py)."""

from __future__ import annotations

import numpy as np
import pytest
from geometry_checks import (
    LIMIT_TOL_DEG,
    PHI_THETA_MIN_DEG,
    RNG_SEED,
    TOL_DEG,
    arm_candidates,
    assert_round_trip,
    assert_within_limits,
    best_arm_cost,
    circ_diff_deg,
    random_requests,
    ref_sample_frame,
    representatives,
    vec_deg,
)

from rig.physics.geometry import (
    AxisLimits,
    angle_between,
    camera_unit,
    forward_deg,
    inverse_deg,
    vec_to_sph,
)


# --------------------------------------------------------------------------- inverse → forward round trip
def test_round_trip_default_limits_1e5():
    rng = np.random.default_rng(RNG_SEED)
    req = random_requests(rng, 100_000)
    limits = AxisLimits()
    m = inverse_deg(*req, limits=limits)
    assert np.all(np.isfinite(m.as_array())), "every θ ≤ 90° geometry is reachable by default"
    assert_within_limits(m, limits)
    assert_round_trip(*req, m)
    # the stage follows the contract literally
    np.testing.assert_allclose(m.stage_vertical_deg, -req[0], atol=1e-12)
    assert circ_diff_deg(m.stage_normal_deg, -req[1]).max() < 1e-9


NARROW_LIMITS = [
    AxisLimits(arm_azimuth=(-90.0, 90.0)),
    AxisLimits(arm_polar=(0.0, 180.0)),
    AxisLimits(arm_polar=(-180.0, 0.0)),
    AxisLimits(stage_vertical=(-60.0, 10.0), stage_normal=(-180.0, 180.0),
               arm_azimuth=(-120.0, 30.0), arm_polar=(-100.0, 120.0)),
    AxisLimits(stage_normal=(0.0, 360.0), arm_azimuth=(0.0, 270.0), arm_polar=(-45.0, 135.0)),
    AxisLimits(stage_normal=(-720.0, 720.0), arm_azimuth=(-400.0, 400.0)),
]


@pytest.mark.parametrize("limits", NARROW_LIMITS)
def test_round_trip_narrow_limits(limits):
    """Finite answers round-trip and respect the limits; NaN only where truly unreachable."""
    rng = np.random.default_rng(11)
    n = 20_000
    req = random_requests(rng, n)
    cur = (rng.uniform(*limits.stage_vertical), rng.uniform(*limits.stage_normal),
           rng.uniform(*limits.arm_azimuth), rng.uniform(*limits.arm_polar))
    m = inverse_deg(*req, limits=limits, current_deg=cur)
    arr = m.as_array()
    finite = np.all(np.isfinite(arr), axis=-1)
    # NaN is all-or-nothing per point
    assert np.all(finite | np.all(np.isnan(arr), axis=-1))
    assert_within_limits(m, limits)
    assert_round_trip(*req, m, mask=finite)
    # brute-force reachability
    ti, pi_, to, po = req

    def stage_ok(tol):
        return (np.any(np.isfinite(representatives(-ti, *limits.stage_vertical, tol=tol)), axis=-1)
                & np.any(np.isfinite(representatives(-pi_, *limits.stage_normal, tol=tol)), axis=-1))

    sub = np.arange(n)
    a0, b0, pole = arm_candidates(*(x[sub] for x in req))
    arm_cost = best_arm_cost(a0, b0, pole, limits, cur[2], cur[3])
    reachable = stage_ok(LIMIT_TOL_DEG)[sub] & np.isfinite(arm_cost)
    surely = stage_ok(-LIMIT_TOL_DEG)[sub] & np.isfinite(best_arm_cost(a0, b0, pole, limits, cur[2], cur[3],
                                                                      tol=-LIMIT_TOL_DEG))
    assert np.all(finite[sub] | ~surely) and np.all(reachable | ~finite[sub])
    # the chosen arm pose is the nearest one (sum of the two arm moves)
    got_cost = np.abs(arr[sub, 2] - cur[2]) + np.abs(arr[sub, 3] - cur[3])
    ok = reachable & finite[sub]
    np.testing.assert_allclose(got_cost[ok], arm_cost[ok], atol=1e-9)
    # the stage representatives are the nearest ones too
    for k, name, want in ((0, "stage_vertical", -ti[sub]), (1, "stage_normal", -pi_[sub])):
        reps = representatives(want, *getattr(limits, name))
        best = np.min(np.where(np.isnan(reps), np.inf, np.abs(reps - cur[k])), axis=-1)
        np.testing.assert_allclose(np.abs(arr[sub, k] - cur[k])[ok], best[ok], atol=1e-9)
    if limits == NARROW_LIMITS[0] or limits == NARROW_LIMITS[1]:
        assert finite.all()       # one branch always fits those


# --------------------------------------------------------------------------- poles
def test_arm_pole_keeps_current_azimuth():
    """b = 0 (camera at the zenith) is the arm's pole: the azimuth is free, keep the current one."""
    rng = np.random.default_rng(12)
    ti, pi_ = rng.uniform(0, 90, 50), rng.uniform(0, 360, 50)
    # the zenith seen from the sample, for α=-θi, β=-φi (a θo = 90° view)
    wo = np.stack([ref_sample_frame(-t, -p).T @ [0, 0, 1] for t, p in zip(ti, pi_)])
    th, ph = np.degrees(vec_to_sph(wo)[0]), np.degrees(vec_to_sph(wo)[1])
    np.testing.assert_allclose(th, 90.0, atol=1e-12)
    for cur_a in (0.0, 37.0, -123.4, 179.0):
        m = inverse_deg(ti, pi_, th, ph, current_deg=(0.0, 0.0, cur_a, 20.0))
        np.testing.assert_allclose(m.arm_polar_deg, 0.0, atol=1e-9)
        np.testing.assert_allclose(m.arm_azimuth_deg, cur_a, rtol=0, atol=1e-12)
        assert_round_trip(ti, pi_, th, ph, m)
    # home view from home keeps everything at zero
    m = inverse_deg(0.0, 0.0, 90.0, 90.0)
    np.testing.assert_allclose(m.as_array(), 0.0, atol=1e-12)


def test_view_pole_theta_o_zero():
    """θo = 0: the camera sits on the (horizontal) sample normal, b = ±90°; φo is kept."""
    rng = np.random.default_rng(13)
    ti, pi_ = rng.uniform(0, 90, 200), rng.uniform(0, 360, 200)
    po = rng.uniform(0, 360, 200)
    m = inverse_deg(ti, pi_, 0.0, po)
    np.testing.assert_allclose(np.abs(m.arm_polar_deg), 90.0, atol=1e-9)
    # φo is irrelevant to the motors at θo = 0
    m2 = inverse_deg(ti, pi_, 0.0, 0.0)
    np.testing.assert_allclose(m.as_array(), m2.as_array(), atol=1e-12)
    got = forward_deg(*m.as_array().T, phi_i_at_pole_deg=pi_, phi_o_at_pole_deg=po)
    assert np.abs(got.theta_o_deg).max() < TOL_DEG
    np.testing.assert_allclose(got.phi_o_deg, po, rtol=0, atol=1e-12)   # the requested φo is emitted
    got0 = forward_deg(*m.as_array().T)
    assert np.all(np.isfinite(got0.phi_o_deg))              # finite even without one
    assert_round_trip(ti, pi_, 0.0, po, m)


def test_incidence_pole_theta_i_zero():
    """θi = 0: α = 0, β = −φi; forward_deg keeps the requested φi, and φo is relative to it."""
    rng = np.random.default_rng(14)
    pi_ = np.r_[0.0, 0.0001, 359.9999, 360.0, rng.uniform(0, 360, 200)]
    to, po = rng.uniform(0.5, 89, pi_.size), rng.uniform(0, 360, pi_.size)
    m = inverse_deg(0.0, pi_, to, po)
    np.testing.assert_allclose(m.stage_vertical_deg, 0.0, rtol=0, atol=1e-12)
    assert circ_diff_deg(m.stage_normal_deg, -pi_).max() < 1e-12
    got = forward_deg(*m.as_array().T, phi_i_at_pole_deg=pi_, phi_o_at_pole_deg=po)
    np.testing.assert_allclose(got.theta_i_deg, 0.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(got.phi_i_deg, pi_ % 360.0, atol=1e-12)
    assert_round_trip(0.0, pi_, to, po, m)
    # without a requested φi the writer still gets a finite value
    assert np.all(np.isfinite(forward_deg(*m.as_array().T).phi_i_deg))
    # φi at the pole is a rotation of the sample about its normal (the beam): only φo − φi
    # decides where the camera goes
    m_a = inverse_deg(0.0, 0.0, 40.0, 10.0)
    m_b = inverse_deg(0.0, 30.0, 40.0, 40.0)
    m_c = inverse_deg(0.0, 30.0, 40.0, 10.0)
    cam = [camera_unit(*np.radians([m.arm_azimuth_deg, m.arm_polar_deg])) for m in (m_a, m_b, m_c)]
    assert angle_between(cam[0], cam[1]) < 1e-12
    assert np.degrees(angle_between(cam[0], cam[2])) > 1.0
    assert float(m_b.stage_normal_deg) - float(m_a.stage_normal_deg) == pytest.approx(-30.0)


def test_both_poles():
    """θi = 0 and θo = 0: camera on the lamp (a, b) = (−90, 90) or its twin; both φ kept."""
    for pi_, po in ((0.0, 0.0), (123.0, 321.0), (359.9999, 0.0001), (360.0, 360.0)):
        m = inverse_deg(0.0, pi_, 0.0, po)
        a, b = float(m.arm_azimuth_deg), float(m.arm_polar_deg)
        assert (circ_diff_deg(a, -90.0) < 1e-9 and abs(b - 90.0) < 1e-9) or \
               (circ_diff_deg(a, 90.0) < 1e-9 and abs(b + 90.0) < 1e-9)
        got = forward_deg(*m.as_array(), phi_i_at_pole_deg=pi_, phi_o_at_pole_deg=po)
        assert got.theta_i_deg == pytest.approx(0.0, abs=1e-12) and got.theta_o_deg < TOL_DEG
        assert got.phi_i_deg == pytest.approx(pi_ % 360.0, abs=1e-12)
        assert got.phi_o_deg == pytest.approx(po % 360.0, abs=1e-12)
    # from home the choice is deterministic: the documented (−90°, 90°)
    m = inverse_deg(0.0, 0.0, 0.0, 0.0)
    np.testing.assert_allclose([m.arm_azimuth_deg, m.arm_polar_deg], [-90.0, 90.0], atol=1e-12)


# --------------------------------------------------------------------------- φ wrap
def test_phi_0_and_360_are_the_same():
    rng = np.random.default_rng(15)
    ti, to, po = rng.uniform(0, 90, 100), rng.uniform(0, 89, 100), rng.uniform(0, 360, 100)
    m0 = inverse_deg(ti, 0.0, to, po).as_array()
    m360 = inverse_deg(ti, 360.0, to, po).as_array()
    np.testing.assert_allclose(m0, m360, atol=1e-9)
    np.testing.assert_allclose(inverse_deg(ti, 45.0, to, 0.0).as_array(),
                               inverse_deg(ti, 45.0, to, 360.0).as_array(), atol=1e-9)
    got = forward_deg(*m360.T, phi_i_at_pole_deg=360.0, phi_o_at_pole_deg=360.0)
    assert np.all(got.phi_i_deg < 360.0) and np.all(got.phi_i_deg >= 0.0)
    np.testing.assert_allclose(circ_diff_deg(got.phi_i_deg, 0.0)[ti > PHI_THETA_MIN_DEG], 0.0, atol=TOL_DEG)
    # negative and beyond-a-turn requests mean the same direction
    np.testing.assert_allclose(inverse_deg(30.0, -30.0, 20.0, 390.0).as_array(),
                               inverse_deg(30.0, 330.0, 20.0, 30.0).as_array(), atol=1e-9)


def test_phi_near_the_cut():
    """359.9999 and 0.0001 are 0.0002° apart: the stage moves 0.0001°, not a turn."""
    m1 = inverse_deg(30.0, 359.9999, 40.0, 359.9999)
    m2 = inverse_deg(30.0, 0.0001, 40.0, 0.0001)
    assert abs(m1.stage_normal_deg - 0.0001) < 1e-9
    assert abs(m2.stage_normal_deg + 0.0001) < 1e-9
    assert np.abs(m1.as_array() - m2.as_array()).max() < 0.01
    g1 = forward_deg(*m1.as_array())
    g2 = forward_deg(*m2.as_array())
    assert g1.phi_i_deg == pytest.approx(359.9999, abs=1e-9)
    assert g1.phi_o_deg == pytest.approx(359.9999, abs=1e-9)
    assert g2.phi_i_deg == pytest.approx(0.0001, abs=1e-9)
    assert g2.phi_o_deg == pytest.approx(0.0001, abs=1e-9)


def test_forward_phi_always_in_range():
    rng = np.random.default_rng(16)
    m = rng.uniform(-1000, 1000, (100_000, 4))
    # awkward motor values: whole turns, tiny offsets around the cut
    m[:1000, 1] = rng.choice([0.0, -0.0, 360.0, -360.0, 720.0, -1e-14, 1e-14, -1e-12], 1000)
    m[1000:2000] = rng.choice([0.0, 90.0, -90.0, 180.0, -180.0, 360.0, -1e-13], (1000, 4))
    got = forward_deg(*m.T)
    for ph in (got.phi_i_deg, got.phi_o_deg):
        assert np.all(np.isfinite(ph))
        assert np.all((ph >= 0.0) & (ph < 360.0)), ph[(ph < 0) | (ph >= 360)]
    # a direction just below the x axis (φ = −1e-15 rad) becomes ~360−, never 360.0
    th, ph = vec_to_sph(np.array([[1.0, -1e-15, 0.1], [1.0, -1e-17, 0.1], [1.0, -1e-300, 0.0]]))
    assert np.all(np.degrees(ph) < 360.0) and np.all(ph >= 0.0)
    # requested pole azimuths are wrapped too
    g = forward_deg(0.0, 0.0, -90.0, 90.0, phi_i_at_pole_deg=[360.0, -10.0, 725.0, 359.99999999999994],
                    phi_o_at_pole_deg=360.0)
    assert np.all((g.phi_i_deg >= 0.0) & (g.phi_i_deg < 360.0))
    np.testing.assert_allclose(circ_diff_deg(g.phi_i_deg, [0.0, 350.0, 5.0, 0.0]), 0.0, atol=1e-9)
    np.testing.assert_allclose(g.phi_o_deg, 0.0, rtol=0, atol=1e-12)
    g = forward_deg(0.0, 0.0, -90.0, 90.0, phi_i_at_pole_deg=-1e-14, phi_o_at_pole_deg=-1e-300)
    assert g.phi_i_deg == pytest.approx(0.0, abs=1e-12) and g.phi_o_deg == pytest.approx(0.0, abs=1e-12)


def test_near_but_not_at_the_pole_phi_is_measured():
    """Only a true pole (sin θ ≲ 1e-12) falls back to the requested azimuth."""
    for theta in (1e-6, 1e-8):                   # degrees; 1.7e-8 and 1.7e-10 rad
        m = inverse_deg(30.0, 10.0, theta, 123.0)
        got = forward_deg(*m.as_array(), phi_i_at_pole_deg=0.0, phi_o_at_pole_deg=0.0)
        assert got.theta_o_deg == pytest.approx(theta, rel=1e-6)
        # round-off ~1e-16 / sin θ rad in φ
        assert circ_diff_deg(got.phi_o_deg, 123.0) < 1e-4
        th, ph = vec_to_sph(vec_deg(theta, 123.0), phi_at_pole=0.0)
        assert np.degrees(ph) == pytest.approx(123.0, abs=1e-9)
