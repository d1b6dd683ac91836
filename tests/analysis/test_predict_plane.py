"""`rig predict` in and across the plane of incidence (issue 31): an isotropic sample's value at Δφ equals its value
at −Δφ, so the interpolant must be continuous through Δφ = 0 and 180°, where the folded views meet. Swept on the
measured paper campaign against its closed-form truth, and on a closed-form dataset whose views avoid the plane."""

import numpy as np
import pytest
from shared import dataset, smooth_brdf

from rig.analysis.incidence_views import containing_triangle, mirrored_views
from rig.analysis.predict import InterpolatingPredictor, measured_domain
from rig.physics.geometry import sph_to_vec

#: Azimuth steps (degrees) either side of the plane: far below any measured spacing.
STEPS_DEG = np.array([-0.01, 0.0, 0.01])


def sweep(predictor, theta_i_deg, theta_o_deg, base_deg):
    """Predictions at Δφ = base + STEPS_DEG for each (θi, θo) pair: (f, u, extrapolated, Δφ) of shape (N, 3)."""
    ti = np.repeat(np.asarray(theta_i_deg, float)[:, None], 3, axis=1)
    to = np.repeat(np.asarray(theta_o_deg, float)[:, None], 3, axis=1)
    dphi = np.broadcast_to(base_deg + STEPS_DEG, ti.shape)
    p = predictor.predict(ti, 0.0, to, dphi)
    return p.brdf_per_sr, p.u_brdf_per_sr, p.extrapolated, dphi


@pytest.mark.parametrize("base_deg", [0.0, 180.0])
def test_the_paper_campaign_is_continuous_through_the_plane_of_incidence_and_covers_the_truth(paper_run, base_deg):
    """Before the views were mirrored across the plane, θi 40°, θo 42.12° gave 0.204 at Δφ = 0 and 0.401 at 0.01°
    (truth 0.517): 36 of these 78 groups jumped by more than 2 % and k = 2 covered 80 %."""
    ds, truth = paper_run
    rng = np.random.default_rng(31)
    theta_i = np.repeat(np.arange(10.0, 71.0, 5.0), 3)
    theta_o = rng.uniform(0.0, 75.0, theta_i.size)
    f, u, extrapolated, dphi = sweep(InterpolatingPredictor(measured_domain(ds)), theta_i, theta_o, base_deg)
    jump = np.ptp(f, axis=1)
    assert np.all(jump <= 0.002 * f.mean(axis=1)), "a step of 0.01° across the plane changes the value"
    assert np.all(jump <= u.min(axis=1)), "the change across the plane exceeds the interpolation's own u"
    assert not extrapolated[:, 1][~extrapolated[:, 0]].any(), "the plane itself is outside a measured hull"
    wi = sph_to_vec(np.radians(theta_i), 0.0)[:, None, :].repeat(3, axis=1)
    wo = sph_to_vec(np.radians(theta_o)[:, None].repeat(3, axis=1), np.radians(dphi))
    covered = np.abs(f - truth(wi, wo)) <= 2 * u
    assert covered.mean() >= 0.9


def test_views_that_avoid_the_plane_still_interpolate_across_it():
    """φo from 15° to 165° only: the plane of incidence lies between a view and its mirror image, inside the domain,
    and a smooth BRDF is interpolated there within its u, the same at ±Δφ."""
    ds = dataset(smooth_brdf, phi_o_deg=np.arange(15.0, 166.0, 30.0))
    predictor = InterpolatingPredictor(measured_domain(ds))
    theta_i = np.array([20.0, 30.0, 40.0, 50.0])
    theta_o = np.array([35.0, 45.0, 25.0, 55.0])
    for base in (0.0, 180.0):
        f, u, extrapolated, dphi = sweep(predictor, theta_i, theta_o, base)
        assert not extrapolated.any()
        assert f[:, 0] == pytest.approx(f[:, 2], rel=1e-12)
        truth = smooth_brdf(theta_i[:, None], 0.0, theta_o[:, None], dphi)
        assert np.all(np.abs(f - truth) <= 2 * u)


def test_mirrored_views_double_the_views_off_the_plane_only():
    xy = np.array([[0.3, 0.0], [0.5, 0.2], [-0.4, 0.6], [0.1, 1e-12]])
    views, source, mirror = mirrored_views(xy)
    assert views.shape == (6, 2) and list(source) == [0, 1, 2, 3, 1, 2]
    assert views[4] == pytest.approx([0.5, -0.2]) and views[5] == pytest.approx([-0.4, -0.6])
    assert np.array_equal(mirror[mirror], np.arange(6))
    assert list(mirror[[0, 3]]) == [0, 3]


def test_the_containing_triangle_and_its_weights_reproduce_the_point():
    corners = np.array([[[0.0, 0.0], [1.0, 0.0], [0.0, 1.0]], [[1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]])
    k, w = containing_triangle(corners, np.array([0.8, 0.6]))
    assert k == 1 and w.sum() == pytest.approx(1.0) and w @ corners[1] == pytest.approx([0.8, 0.6])
    k, w = containing_triangle(corners, np.array([0.2, 0.3]))
    assert k == 0 and w == pytest.approx([0.5, 0.2, 0.3])
    assert containing_triangle(corners, np.array([1.2, 0.5])) is None
    assert containing_triangle(np.array([[[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]]), np.array([1.0, 1.0])) is None
