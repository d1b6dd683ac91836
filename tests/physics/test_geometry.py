"""Tests of rig.physics.geometry against the contract docs/geometry.md.

Tolerances
----------
* Directions are compared by the angle between the requested and the achieved unit
  vectors: < 1e-9 degrees everywhere (the contract's accuracy), including the poles.
* θ is compared directly (|Δθ| < 1e-9°).
* φ is compared directly (circularly) only where θ ≥ 0.1°.  Double precision carries a
  direction to ~1e-15 rad, so an azimuth computed from a vector is only good to about
  1e-15 rad / sin θ: at θ = 0.1° that is ~6e-11°, safely inside 1e-9°, but at θ = 1e-3°
  it is ~1e-9° and below that it is meaningless (the contract: readers must not depend
  on φ at the pole).  Everywhere else we check |Δφ|·sin θ < 1e-9° (i.e. the azimuth
  error is consistent with a direction error within the contract), and at the exact
  poles that the requested φ is returned (forward_deg's pole handling).
* Computed angles are never compared with ``==``: trigonometric kernels differ between CPU
  classes (numpy dispatches AVX2/FMA3 or AVX-512 code), so even "exact" values such as a
  pole's θ = 0 or a clipped limit are compared within 1e-12 (CI runs this file a second time
  with numpy's SIMD dispatch restricted, see .ci/run).
* Round-off alone gives errors ~1e-13°.  The only larger, deliberate error: a requested
  angle whose representative lies within 1e-12 turn (3.6e-10°) outside a limit is
  snapped onto the limit (inverse_deg's tolerance) - still inside the 1e-9° contract.
"""

from __future__ import annotations

import numpy as np
import pytest
from geometry_checks import (
    PHI_THETA_MIN_DEG,
    RNG_SEED,
    TOL_DEG,
    angle_deg,
    circ_diff_deg,
    ref_directions,
    ref_sample_frame,
    vec_deg,
)
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from rig.physics import geometry as geo
from rig.physics.geometry import (
    AXIS_NAMES,
    BrdfAngles,
    angle_between,
    camera_frame,
    camera_unit,
    centre_pattern,
    directions_scs,
    forward_deg,
    inverse_deg,
    mirror_direction,
    rot_y,
    rot_z,
    rotation_matrix,
    sample_frame,
    sph_to_vec,
    vec_to_sph,
    wrap_2pi,
    wrap_pi,
)


# --------------------------------------------------------------------------- spherical basics
def test_sph_to_vec_axes():
    np.testing.assert_allclose(sph_to_vec(0.0, 1.234), [0, 0, 1], atol=1e-16)
    np.testing.assert_allclose(sph_to_vec(np.pi / 2, 0.0), [1, 0, 0], atol=1e-16)
    np.testing.assert_allclose(sph_to_vec(np.pi / 2, np.pi / 2), [0, 1, 0], atol=1e-16)
    np.testing.assert_allclose(sph_to_vec(np.pi, 0.3), [0, 0, -1], atol=1e-15)
    # φ = atan2(y, x): the 3rd quadrant is φ in (180, 270)
    th, ph = vec_to_sph(np.array([-1.0, -1.0, 0.0]))
    assert np.isclose(np.degrees(th), 90.0) and np.isclose(np.degrees(ph), 225.0)
    assert sph_to_vec(np.zeros((4, 5)), np.zeros(5)).shape == (4, 5, 3)


def test_vec_to_sph_round_trip():
    rng = np.random.default_rng(RNG_SEED)
    n = 100_000
    theta = np.arccos(rng.uniform(-1.0, 1.0, n))
    phi = rng.uniform(0.0, 2 * np.pi, n)
    v = sph_to_vec(theta, phi)
    np.testing.assert_allclose(np.linalg.norm(v, axis=-1), 1.0, atol=1e-15)
    th2, ph2 = vec_to_sph(v)
    assert np.all((ph2 >= 0.0) & (ph2 < 2 * np.pi))
    assert np.abs(th2 - theta).max() < 1e-14
    away = np.sin(theta) > 1e-3
    assert np.abs(wrap_pi(ph2 - phi))[away].max() < 1e-12
    assert angle_between(sph_to_vec(th2, ph2), v).max() < 1e-15
    # scale does not matter
    th3, ph3 = vec_to_sph(7.5 * v)
    np.testing.assert_allclose(th3, th2, atol=1e-15)
    np.testing.assert_allclose(wrap_pi(ph3 - ph2), 0.0, atol=1e-13)


def test_vec_to_sph_pole_keeps_requested_phi():
    th, ph = vec_to_sph(np.array([0.0, 0.0, 1.0]), phi_at_pole=1.25)
    assert th == pytest.approx(0.0, abs=1e-15) and ph == pytest.approx(1.25, abs=1e-15)
    th, ph = vec_to_sph(np.array([0.0, 0.0, -1.0]), phi_at_pole=0.5)
    assert th == pytest.approx(np.pi) and ph == pytest.approx(0.5, abs=1e-15)
    # the kept azimuth is wrapped too, and is broadcast per vector
    v = np.array([[0.0, 0.0, 1.0], [1e-20, -1e-20, 1.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    th, ph = vec_to_sph(v, phi_at_pole=np.array([2 * np.pi + 0.5, -0.5, 3.0, 2 * np.pi]))
    np.testing.assert_allclose(ph, [0.5, 2 * np.pi - 0.5, 0.0, 0.0], atol=1e-15)
    assert np.all(np.isfinite(ph))
    # default: still a finite value
    assert np.isfinite(vec_to_sph(np.zeros(3))[1])


def test_wrap_2pi_edges():
    tiny = np.array([0.0, -0.0, 2 * np.pi, -2 * np.pi, 4 * np.pi, -1e-300, -1e-17, -1e-15,
                     1e-300, np.nextafter(2 * np.pi, 0), 1e6, -1e6])
    w = wrap_2pi(tiny)
    assert np.all((w >= 0.0) & (w < 2 * np.pi))
    assert np.all(np.degrees(w) < 360.0)
    # values that round to 2π become 0, not 2π − ε
    for edge in (2 * np.pi, -1e-300, -1e-17):
        assert wrap_2pi(edge) == pytest.approx(0.0, abs=1e-15), edge
    assert wrap_2pi(-1e-15) == pytest.approx(2 * np.pi - 1e-15, abs=1e-15)


def test_wrap_360():
    x = np.array([0.0, -0.0, 360.0, -360.0, 720.0, -1e-14, -1e-300, 1e-300, 359.99999999999994,
                  -30.0, 390.0, 1e9 + 0.5])
    w = geo.wrap_360(x)
    assert np.all((w >= 0.0) & (w < 360.0))
    np.testing.assert_allclose(w[[0, 1, 2, 3, 4, 5, 6]], 0.0, rtol=0, atol=1e-12)     # 0, never ~360
    np.testing.assert_allclose(w[7:], [1e-300, 359.99999999999994, 330.0, 30.0, 280.5], rtol=1e-15)


def test_wrap_pi_range():
    x = np.array([np.pi, -np.pi, 3 * np.pi, 0.0, np.pi - 1e-12, -np.pi + 1e-12, 1e5])
    w = wrap_pi(x)
    assert np.all((w >= -np.pi) & (w < np.pi))
    assert wrap_pi(np.pi) == pytest.approx(-np.pi)
    np.testing.assert_allclose(np.cos(w), np.cos(x), atol=1e-10)
    np.testing.assert_allclose(np.sin(w), np.sin(x), atol=1e-10)


@settings(max_examples=300, deadline=None)
@given(st.floats(-1e7, 1e7, allow_nan=False))
def test_wrap_2pi_property(x):
    w = float(wrap_2pi(x))
    assert 0.0 <= w < 2 * np.pi
    assert np.degrees(w) < 360.0
    assert abs(np.sin(w) - np.sin(x)) < 1e-8 and abs(np.cos(w) - np.cos(x)) < 1e-8


@pytest.mark.parametrize("eps", [1e-10, 1e-12, 1e-14, 1e-7, 3e-5])
def test_angle_between_tiny_and_near_pi(eps):
    rng = np.random.default_rng(1)
    u = sph_to_vec(np.arccos(rng.uniform(-1, 1, 200)), rng.uniform(0, 2 * np.pi, 200))
    # rotate each u by eps about a perpendicular axis
    perp = np.cross(u, rng.normal(size=u.shape))
    perp /= np.linalg.norm(perp, axis=-1, keepdims=True)
    v = u * np.cos(eps) + np.cross(perp, u) * np.sin(eps)
    # v itself is only representable to ~1e-16 absolute, hence the atol
    np.testing.assert_allclose(angle_between(u, v), eps, rtol=1e-6, atol=4e-16)
    # exactly representable pairs: relative accuracy at the level of double precision
    x = np.array([1.0, 0.0, 0.0])
    assert angle_between(x, np.array([1.0, np.tan(eps), 0.0])) == pytest.approx(eps, rel=1e-14)
    assert angle_between(x, np.array([1.0, 0.0, -np.tan(eps)])) == pytest.approx(eps, rel=1e-14)
    w = -u * np.cos(eps) + np.cross(perp, u) * np.sin(eps)       # π - eps from u
    np.testing.assert_allclose(angle_between(u, w), np.pi - eps, rtol=0, atol=1e-15)
    # not sensitive to the vectors' lengths
    np.testing.assert_allclose(angle_between(3.0 * u, 0.5 * v), eps, rtol=1e-6, atol=4e-16)


def test_angle_between_basic():
    x, y, z = np.eye(3)
    assert angle_between(x, y) == pytest.approx(np.pi / 2)
    assert angle_between(x, x) == pytest.approx(0.0, abs=1e-15)
    assert angle_between(x, -x) == pytest.approx(np.pi)
    assert angle_between(x, np.array([1.0, 1.0, 0.0])) == pytest.approx(np.pi / 4)


# --------------------------------------------------------------------------- rotations
def test_rotations_right_handed():
    x, y, z = np.eye(3)
    q = np.pi / 2
    np.testing.assert_allclose(rot_z(q) @ x, y, atol=1e-15)
    np.testing.assert_allclose(rot_z(q) @ y, -x, atol=1e-15)
    np.testing.assert_allclose(rot_y(q) @ z, x, atol=1e-15)
    np.testing.assert_allclose(rot_y(q) @ x, -z, atol=1e-15)
    np.testing.assert_allclose(rotation_matrix(x, q) @ y, z, atol=1e-15)


def test_rotation_matrix_vs_scipy_and_orthonormal():
    rng = np.random.default_rng(2)
    axes = rng.normal(size=(500, 3))
    axes /= np.linalg.norm(axes, axis=-1, keepdims=True)
    ang = rng.uniform(-10, 10, 500)
    r = rotation_matrix(axes, ang)
    ref = Rotation.from_rotvec(axes * ang[:, None]).as_matrix()
    np.testing.assert_allclose(r, ref, atol=1e-13)
    np.testing.assert_allclose(r @ np.swapaxes(r, -1, -2), np.broadcast_to(np.eye(3), r.shape), atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(r), 1.0, atol=1e-14)
    assert rot_z(np.zeros(7)).shape == (7, 3, 3)


def test_sample_frame_home_and_reference():
    np.testing.assert_allclose(sample_frame(0.0, 0.0), geo.M0, rtol=0, atol=1e-15)
    # home: n faces the lamp (0,-1,0), x = (1,0,0), y = (0,0,1)
    f = sample_frame(0.0, 0.0)
    np.testing.assert_allclose(f[:, 0], [1, 0, 0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(f[:, 1], [0, 0, 1], rtol=0, atol=1e-15)
    np.testing.assert_allclose(f[:, 2], [0, -1, 0], rtol=0, atol=1e-15)
    rng = np.random.default_rng(3)
    al, be = rng.uniform(-400, 400, (2, 300))
    f = sample_frame(np.radians(al), np.radians(be))
    for k in range(len(al)):
        np.testing.assert_allclose(f[k], ref_sample_frame(al[k], be[k]), atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(f), 1.0, atol=1e-14)        # right-handed
    np.testing.assert_allclose(np.cross(f[:, :, 0], f[:, :, 1]), f[:, :, 2], atol=1e-14)
    # the sample normal stays horizontal (α is about the vertical Z, β about n)
    np.testing.assert_allclose(f[:, 2, 2], 0.0, atol=1e-15)


def test_camera_unit_and_frame():
    np.testing.assert_allclose(camera_unit(0.0, 0.0), [0, 0, 1])
    np.testing.assert_allclose(camera_frame(0.0, 0.0), np.eye(3))
    rng = np.random.default_rng(4)
    a, b = rng.uniform(-2 * np.pi, 2 * np.pi, (2, 1000))
    fr = camera_frame(a, b)
    np.testing.assert_allclose(fr[..., :, 2], camera_unit(a, b), atol=1e-15)
    np.testing.assert_allclose(np.linalg.det(fr), 1.0, atol=1e-14)
    np.testing.assert_allclose(camera_unit(a, b), (rot_z(a) @ rot_y(b))[..., :, 2], atol=1e-15)


def test_directions_scs_vs_independent_reference():
    rng = np.random.default_rng(5)
    m = rng.uniform(-360, 360, (200, 4))
    wi, wo = directions_scs(*np.radians(m).T)
    for k in range(len(m)):
        rwi, rwo = ref_directions(*m[k])
        np.testing.assert_allclose(wi[k], rwi, atol=1e-14)
        np.testing.assert_allclose(wo[k], rwo, atol=1e-14)


# --------------------------------------------------------------------------- documented consequences
def test_lamp_direction_gcs():
    np.testing.assert_array_equal(geo.LAMP_DIRECTION_GCS, [0.0, -1.0, 0.0])
    lamp_aperture = np.array([0.0, -0.92, 0.0])
    np.testing.assert_allclose(lamp_aperture / np.linalg.norm(lamp_aperture), geo.LAMP_DIRECTION_GCS)
    # whatever the motors, ωi (SCS) maps back to (0, -1, 0) in the GCS
    rng = np.random.default_rng(6)
    m = np.radians(rng.uniform(-360, 360, (500, 4)))
    wi, _ = directions_scs(*m.T)
    f = sample_frame(m[:, 0], m[:, 1])
    np.testing.assert_allclose(np.einsum("kij,kj->ki", f, wi),
                               np.broadcast_to([0.0, -1.0, 0.0], wi.shape), atol=1e-15)


def test_home_position():
    got = forward_deg(0.0, 0.0, 0.0, 0.0)
    assert got.theta_i_deg == pytest.approx(0.0, abs=1e-12)
    assert got.theta_o_deg == pytest.approx(90.0, abs=1e-12)
    assert got.phi_o_deg == pytest.approx(90.0, abs=1e-12)
    wi, wo = directions_scs(0.0, 0.0, 0.0, 0.0)
    np.testing.assert_allclose(wi, [0, 0, 1], rtol=0, atol=1e-16)     # normal faces the lamp
    np.testing.assert_allclose(wo, [0, 1, 0], atol=1e-16)  # camera on GCS +Z = sample y
    assert isinstance(got, BrdfAngles)


def test_stage_gives_incidence():
    """α = −θi, β = −φi gives the incidence (θi, φi), whatever the arm does."""
    ti, pi_ = np.meshgrid(np.r_[0.0, 1e-6, np.arange(5.0, 90.1, 5.0), 89.999],
                          np.r_[0.0, 1e-9, 0.0001, np.arange(15.0, 360.0, 15.0), 359.9999])
    ti, pi_ = ti.ravel(), pi_.ravel()
    rng = np.random.default_rng(7)
    a, b = rng.uniform(-180, 180, (2, ti.size))
    got = forward_deg(-ti, -pi_, a, b, phi_i_at_pole_deg=pi_)
    np.testing.assert_allclose(got.theta_i_deg, ti, atol=TOL_DEG, rtol=0)
    assert circ_diff_deg(got.phi_i_deg, pi_)[ti >= PHI_THETA_MIN_DEG].max() < TOL_DEG
    assert angle_deg(vec_deg(ti, pi_), vec_deg(got.theta_i_deg, got.phi_i_deg)).max() < TOL_DEG
    np.testing.assert_allclose(got.phi_i_deg[ti == 0], pi_[ti == 0], rtol=0, atol=1e-12)   # kept at the pole


def test_camera_at_lamp_is_exact_retro():
    """(a, b) = (−90°, 90°) puts the camera on the lamp: ωo = ωi for any stage position."""
    np.testing.assert_allclose(camera_unit(np.radians(-90.0), np.radians(90.0)), [0, -1, 0], atol=1e-16)
    rng = np.random.default_rng(8)
    al, be = rng.uniform(-90, 90, 1000), rng.uniform(-360, 360, 1000)
    wi, wo = directions_scs(np.radians(al), np.radians(be), np.radians(-90.0), np.radians(90.0))
    assert angle_between(wi, wo).max() < 1e-15
    got = forward_deg(al, be, -90.0, 90.0)
    far = got.theta_i_deg > PHI_THETA_MIN_DEG
    assert np.abs(got.theta_o_deg - got.theta_i_deg).max() < 1e-12
    assert circ_diff_deg(got.phi_o_deg, got.phi_i_deg)[far].max() < 1e-10
    # ... and the inverse of a retro request (θi=θo, φi=φo) is this arm pose (or its twin)
    ti = rng.uniform(0, 90, 1000)
    pi_ = rng.uniform(0, 360, 1000)
    m = inverse_deg(ti, pi_, ti, pi_)
    cam = camera_unit(np.radians(m.arm_azimuth_deg), np.radians(m.arm_polar_deg))
    np.testing.assert_allclose(cam, np.broadcast_to([0, -1, 0], cam.shape), atol=1e-14)


def test_mirror_direction():
    rng = np.random.default_rng(9)
    th = rng.uniform(0, np.pi / 2, 1000)
    ph = rng.uniform(0, 2 * np.pi, 1000)
    m = mirror_direction(sph_to_vec(th, ph))
    th2, ph2 = vec_to_sph(m)
    np.testing.assert_allclose(th2, th, atol=1e-14)
    assert np.abs(wrap_pi(ph2 - ph - np.pi))[np.sin(th) > 1e-6].max() < 1e-12
    assert mirror_direction(np.array([0.0, 0.0, 1.0]))[2] == pytest.approx(1.0, abs=1e-15)
    # the mirror is a reflection about z of the incidence: ωi + ωo ∥ z
    s = sph_to_vec(th, ph) + m
    np.testing.assert_allclose(s[:, :2], 0.0, atol=1e-15)


# --------------------------------------------------------------------------- centred patterns
TABLE2_THETA = [3.3, 10.7, 21.3, 34.8, 50.8, 69.3]
TABLE2_PHI = [25.7, 51.4, 77.1, 102.9, 128.6, 154.3, 180, 205.7, 231.4, 257.1, 282.9, 308.6, 334.3, 360]


def _table2():
    th, ph = np.meshgrid(np.radians(TABLE2_THETA), np.radians(TABLE2_PHI), indexing="ij")
    return th.ravel(), ph.ravel()


def test_centre_pattern_identity_for_z():
    th, ph = _table2()
    d = centre_pattern(th, ph, np.array([0.0, 0.0, 1.0]))
    np.testing.assert_allclose(d, sph_to_vec(th, ph), rtol=0, atol=1e-16)
    d = centre_pattern(th, ph, np.array([0.0, 0.0, 2.5]))        # not normalised
    np.testing.assert_allclose(d, sph_to_vec(th, ph), atol=1e-16)


@pytest.mark.parametrize("phi_i", [0.0, 23.0, 45.0, 359.9999])
def test_centre_pattern_theta_i_zero_is_table2(phi_i):
    """For θi = 0 centring on incidence, mirror or normal gives Table 2 literally."""
    th, ph = _table2()
    wi = sph_to_vec(0.0, np.radians(phi_i))
    for centre in (wi, mirror_direction(wi), np.array([0.0, 0.0, 1.0])):
        d = centre_pattern(th, ph, centre)
        t2, p2 = vec_to_sph(d)
        np.testing.assert_allclose(np.degrees(t2), np.repeat(TABLE2_THETA, len(TABLE2_PHI)), atol=1e-12)
        assert circ_diff_deg(np.degrees(p2), np.degrees(ph)).max() < 1e-12


def test_centre_pattern_is_the_minimal_rotation():
    rng = np.random.default_rng(20)
    th, ph = _table2()
    th = np.r_[0.0, th]
    ph = np.r_[1.0, ph]
    pat = sph_to_vec(th, ph)
    centres = sph_to_vec(np.r_[np.arccos(rng.uniform(-1, 1, 200)), 1e-9, np.pi / 2, np.pi - 1e-9, np.pi],
                         np.r_[rng.uniform(0, 2 * np.pi, 200), 0.3, 0.0, 1.0, 0.0])
    for c in centres:
        d = centre_pattern(th, ph, c)
        np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-15)
        # the pattern's centre (θ' = 0) lands on the centre
        assert angle_between(d[0], c) < 1e-14
        # angles from the centre and between pattern points are preserved
        np.testing.assert_allclose(angle_between(d, c), th, atol=1e-13)
        g1 = angle_between(pat[:, None], pat[None, :])
        g2 = angle_between(d[:, None], d[None, :])
        np.testing.assert_allclose(g2, g1, atol=1e-13)
        # proper rotation (no reflection): orientation of triples preserved
        tri = np.linalg.det(np.stack([pat[1:4], pat[4:7]]))
        tri2 = np.linalg.det(np.stack([d[1:4], d[4:7]]))
        np.testing.assert_allclose(tri2, tri, atol=1e-13)
        # minimal: vectors along the rotation axis z × c are unchanged
        axis = np.cross([0.0, 0.0, 1.0], c)
        if np.linalg.norm(axis) > 1e-6:
            axis /= np.linalg.norm(axis)
            ta, pa = vec_to_sph(axis)
            np.testing.assert_allclose(centre_pattern(np.atleast_1d(ta), np.atleast_1d(pa), c)[0],
                                       axis, atol=1e-14)
            # and the rotation is about that axis by the angle between z and c
            zc = angle_between(np.array([0.0, 0.0, 1.0]), c)
            ref = Rotation.from_rotvec(axis * zc).as_matrix()
            np.testing.assert_allclose(d, pat @ ref.T, atol=1e-13)


def test_centre_pattern_on_oblique_incidence():
    """Centred on ωi = (60°, 90°): the rotation is 60° about −x."""
    wi = vec_deg(60.0, 90.0)
    d = centre_pattern(np.radians([10.0, 10.0]), np.radians([0.0, 180.0]), wi)
    np.testing.assert_allclose(angle_deg(d, wi), 10.0, atol=1e-12)
    # rotation axis is z × ωi = −x: the pattern's ±y directions stay in the y–z plane
    d = centre_pattern(np.radians([10.0, 10.0]), np.radians([90.0, 270.0]), wi)
    t, p = vec_to_sph(d)
    np.testing.assert_allclose(np.degrees(t), [70.0, 50.0], atol=1e-12)
    np.testing.assert_allclose(np.degrees(p), [90.0, 90.0], atol=1e-12)


# --------------------------------------------------------------------------- API
def test_public_api():
    assert AXIS_NAMES == ("stage_vertical", "stage_normal", "arm_azimuth", "arm_polar")
    m = inverse_deg(10.0, 20.0, 30.0, 40.0)
    assert m.as_array().shape == (4,)
    assert inverse_deg(np.zeros((3, 2)), 0.0, 30.0, 0.0).as_array().shape == (3, 2, 4)
    assert isinstance(forward_deg(0, 0, 0, 0), BrdfAngles)
