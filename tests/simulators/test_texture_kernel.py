"""The compiled value noise (simulators/_noise_kernel.c) against texture.value_noise's numpy code.

The kernel computes the same lattice values (the same hash, Cephes' ndtri as scipy's, exp) and blends
them in the same order, so the two agree to the last bit or two; the tests allow 1e-13 relative.
"""

from __future__ import annotations

import numpy as np
import pytest

from rig.simulators import texture
from rig.simulators.texture import GlintTexture, value_noise

pytestmark = pytest.mark.skipif(texture._noise_kernel is None, reason="the compiled value noise was not built")
RTOL = 1e-13


def numpy_value_noise(coords: list[np.ndarray], contrast: float, seed: int) -> np.ndarray:
    """texture.value_noise with the kernel hidden: the numpy code of an install without a C compiler."""
    kernel, texture._noise_kernel = texture._noise_kernel, None
    try:
        return value_noise(coords, contrast, seed)
    finally:
        texture._noise_kernel = kernel


@pytest.mark.parametrize("axes", [1, 2, 3, 4])
def test_dense_points_equal_the_numpy_value_noise(axes):
    rng = np.random.default_rng(axes)
    coords = [rng.uniform(-7.3, 5.1, 20_000) + 1e3 * k for k in range(axes)]
    np.testing.assert_allclose(value_noise(coords, 0.2, 11), numpy_value_noise(coords, 0.2, 11), rtol=RTOL)


@pytest.mark.parametrize(("axes", "longest"), [(axes, k) for axes in (2, 3, 4) for k in range(axes)])
@pytest.mark.parametrize("points", [1, 2, 7, 60, 3001])
def test_any_axis_can_be_the_table_s_fastest(axes, longest, points):
    """The table's fastest axis is the longest; the prefix of the hash chain shared by its nodes is longer
    the more points there are (none, some axes or all of them)."""
    rng = np.random.default_rng(10 * axes + longest)
    coords = [rng.uniform(-2.5, 1.5, points) + 7.0 * k for k in range(axes)]
    coords[longest] = rng.uniform(-40.0, 35.0, points)
    np.testing.assert_allclose(value_noise(coords, 0.3, 21), numpy_value_noise(coords, 0.3, 21), rtol=RTOL)


def test_points_near_each_other_far_out_equal_the_numpy_value_noise():
    """Beyond 2^51 (no table there) and just below it, where the table finds floors by rounding at 2^52."""
    rng = np.random.default_rng(5)
    for offset in (2.0 ** 51 - 64.0, 2.0 ** 51 + 1024.0, -(2.0 ** 51) + 32.0, -(2.0 ** 60)):
        coords = [offset + rng.uniform(0.0, 30.0, 301), rng.uniform(-3.0, 3.0, 301)]
        np.testing.assert_allclose(value_noise(coords, 0.2, 4), numpy_value_noise(coords, 0.2, 4), rtol=RTOL)


def test_scattered_points_hashed_per_corner_equal_the_numpy_value_noise():
    """Points far apart on the lattice: too large a block for the table, every corner is hashed."""
    rng = np.random.default_rng(3)
    coords = [rng.uniform(-1e12, 1e12, 500) for _ in range(4)]
    np.testing.assert_allclose(value_noise(coords, 0.1, -5), numpy_value_noise(coords, 0.1, -5), rtol=RTOL)


def test_broadcast_and_scalar_coordinates_keep_their_shape():
    x = np.linspace(0.0, 3.0, 7)[:, None]
    y = np.array([0.25, 1.75])
    got = value_noise([x, y], 0.3, 2)
    assert got.shape == (7, 2)
    np.testing.assert_allclose(got, numpy_value_noise([x, y], 0.3, 2), rtol=RTOL)
    assert value_noise([0.5, 2.5], 0.3, 2).shape == ()
    assert value_noise([0.5, 2.5], 0.3, 2) == pytest.approx(float(numpy_value_noise([0.5, 2.5], 0.3, 2)), rel=RTOL)


def test_the_values_do_not_depend_on_how_the_points_are_split():
    """Each run of points builds its own table: a lattice value is a function of its node alone."""
    rng = np.random.default_rng(4)
    coords = [rng.uniform(0, 30, 5000) for _ in range(4)]
    whole, parts = np.empty(5000), np.empty(5000)
    texture._noise_kernel.value_noise(coords, 0.1, 9, whole, 0, 5000)
    for start, stop in [(0, 1), (1, 1), (1, 2600), (2600, 5000)]:
        texture._noise_kernel.value_noise(coords, 0.1, 9, parts, start, stop)
    np.testing.assert_array_equal(parts, whole)


def test_lattice_nodes_take_the_lattice_values():
    ix, iy = np.meshgrid(np.arange(-3, 4), np.arange(2, 6), indexing="ij")
    nodes = texture.noise_lattice((ix, iy), 0.25, 8)
    np.testing.assert_allclose(value_noise([ix.astype(float), iy.astype(float)], 0.25, 8), nodes, rtol=RTOL)


def test_a_full_frame_glint_equals_the_numpy_one():
    """The glint of a frame's lit pixels (half vectors and positions change together), as the camera asks."""
    glint = GlintTexture(contrast=0.1, grain_m=5e-4, angle_rad=np.radians(2.0), seed=1)
    y_m, x_m = (a.ravel() for a in np.mgrid[-0.02:0.02:300j, -0.03:0.03:400j])
    wi = np.array([0.5, 0.0, np.sqrt(0.75)])
    camera = np.array([0.0, 0.0, 1.0])
    wo = camera - np.stack([x_m, y_m, np.zeros_like(x_m)], axis=1)
    wo /= np.linalg.norm(wo, axis=1)[:, None]
    got = glint(x_m, y_m, wi, wo)
    kernel, texture._noise_kernel = texture._noise_kernel, None
    try:
        expected = glint(x_m, y_m, wi, wo)
    finally:
        texture._noise_kernel = kernel
    np.testing.assert_allclose(got, expected, rtol=RTOL)


@pytest.mark.parametrize("bad", [np.nan, np.inf, 2.0 ** 63])
def test_coordinates_that_are_not_finite_lattice_points_are_refused(bad):
    with pytest.raises(ValueError, match="finite lattice coordinates"):
        value_noise([np.array([0.5, bad]), np.array([1.0, 2.0])], 0.1, 1)


def test_arguments_of_the_wrong_kind_are_refused():
    out = np.empty(3)
    with pytest.raises(TypeError, match="1-D float64"):
        texture._noise_kernel.value_noise([np.arange(3)], 0.1, 1, out, 0, 3)
    with pytest.raises(ValueError, match="has 2 values"):
        texture._noise_kernel.value_noise([np.zeros(3), np.zeros(2)], 0.1, 1, out, 0, 3)
    with pytest.raises(ValueError, match="1 to 4 axes"):
        texture._noise_kernel.value_noise([np.zeros(3)] * 5, 0.1, 1, out, 0, 3)
    with pytest.raises(ValueError, match="not within"):
        texture._noise_kernel.value_noise([np.zeros(3)], 0.1, 1, out, 2, 4)
