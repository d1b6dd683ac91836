"""The compiled rays on the lit sample (simulators/_view_kernel.c) against lit_view's numpy code.

Both take the same row and column terms and do the same operations in the same order, so they agree bit
for bit: the lit pixels, the hits and ωo. tests/simulators/test_sim_camera.py holds lit_view (whichever
runs) to rig.physics.optics.
"""

import numpy as np
import pytest

from rig.config.rigfile import RigConfig, camera_optics
from rig.core.values import Window
from rig.physics.geometry import inverse_deg, sample_frame
from rig.simulators import camera
from rig.simulators.camera import lit_view

pytestmark = pytest.mark.skipif(camera._view_kernel is None, reason="the compiled rays were not built")
OPTICS = camera_optics(RigConfig())
FULL = Window(0, 0, OPTICS.width_px, OPTICS.height_px)


def view(theta_i, phi_i, theta_o, phi_o, box=FULL, radius_m=0.025):
    """lit_view's arguments for a pose at BRDF angles (degrees)."""
    alpha, beta, a, b = np.radians(inverse_deg(theta_i, phi_i, theta_o, phi_o).as_array())
    return OPTICS, a, b, box, sample_frame(alpha, beta), radius_m


def numpy_lit_view(*args):
    kernel, camera._view_kernel = camera._view_kernel, None
    try:
        return lit_view(*args)
    finally:
        camera._view_kernel = kernel


@pytest.mark.parametrize("angles", [(0, 0, 10, 90), (30, 0, 35, 180), (60, 45, 20, 270), (85, 0, 3.3, 0),
                                    (80, 0, 80, 180), (20, 0, 85, 90)])
def test_the_compiled_rays_equal_the_numpy_ones(angles):
    compiled, reference = lit_view(*view(*angles)), numpy_lit_view(*view(*angles))
    assert compiled[0].any()
    for got, expected in zip(compiled, reference):
        assert got.shape == expected.shape and got.dtype == expected.dtype
        np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("box", [Window(600, 400, 7, 300), Window(0, 0, 1, 1), Window(690, 515, 10, 10)])
def test_boxes_of_any_shape_are_traced_alike(box):
    for got, expected in zip(lit_view(*view(40, 0, 20, 90, box)), numpy_lit_view(*view(40, 0, 20, 90, box))):
        np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("radius_m", [0.0, -1.0, 1e-4])
def test_a_tiny_empty_or_dark_spot_lights_the_same_pixels(radius_m):
    for got, expected in zip(lit_view(*view(30, 0, 30, 180, radius_m=radius_m)),
                             numpy_lit_view(*view(30, 0, 30, 180, radius_m=radius_m))):
        np.testing.assert_array_equal(got, expected)


def test_arrays_of_the_wrong_shape_are_refused():
    rows, cols = np.zeros((7, 3)), np.zeros((7, 4))
    lit, xy, wo = np.empty((3, 4), bool), np.empty((12, 2)), np.empty((12, 3))
    camera._view_kernel.lit_rays(rows, cols, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, lit, xy, wo)      # the shapes it takes
    with pytest.raises(ValueError, match="rows"):
        camera._view_kernel.lit_rays(np.zeros((6, 3)), cols, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, lit, xy, wo)
    with pytest.raises(ValueError, match="lit"):
        camera._view_kernel.lit_rays(rows, cols, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, np.empty((3, 4), float), xy, wo)
    with pytest.raises(ValueError, match="height·width"):
        camera._view_kernel.lit_rays(rows, cols, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0, lit, xy[:5], wo)
