"""A fit weighs by the point-to-point u and propagates the shared calibrations apart (issue 34)."""

import numpy as np
import pytest

from rig.analysis.fit import fit
from rig.physics.brdf_models import get_model
from rig.physics.geometry import sph_to_vec


def directions(n: int, seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    wi = sph_to_vec(np.radians(rng.uniform(0, 80, n)), np.radians(rng.uniform(0, 360, n)))
    wo = sph_to_vec(np.radians(rng.uniform(0, 80, n)), np.radians(rng.uniform(0, 360, n)))
    return wi, wo


def test_a_shared_calibration_moves_a_scale_parameter_by_its_relative_u():
    """Lambert: f = kd/π, so a 2 % error shared by every point is a 2 % error of kd, whatever the scatter."""
    wi, wo = directions(200)
    rng = np.random.default_rng(1)
    f = 0.6 / np.pi * (1 + 0.003 * rng.standard_normal(200))
    u = np.full(200, 0.003 * 0.6 / np.pi)
    res = fit("lambert", wi, wo, f, u, shared={"calibration": np.full(200, 0.02)})
    assert res.stderr_correlated["kd"] == pytest.approx(0.02 * res.params["kd"], rel=1e-3)
    assert res.stderr["kd"] < 0.1 * res.stderr_correlated["kd"]         # 200 points average the scatter
    assert res.to_json()["stderr_correlated"]["kd"] == res.stderr_correlated["kd"]


def test_independent_sources_add_in_quadrature_and_shape_parameters_do_not_move():
    """Modified Phong: kd and ks scale with f, the exponent n does not; two filters' errors on two halves."""
    wi, wo = directions(300, seed=2)
    params = {"kd": 0.3, "ks": 0.4, "n": 40.0}
    f = get_model("modified_phong")(wi, wo, params)
    u = 0.002 * f
    half = np.arange(300) < 150
    shared = {"calibration": np.full(300, 0.02), "filter 2": np.where(half, 0.01, 0.0),
              "filter 3": np.where(half, 0.0, 0.01)}
    res = fit("modified_phong", wi, wo, f, u, shared=shared)
    expected = np.hypot(0.02, 0.01 / np.sqrt(2))          # the two filters' halves: each moves the mean by ½
    assert res.stderr_correlated["kd"] / res.params["kd"] == pytest.approx(expected, rel=0.1)
    kd_rel = res.stderr_correlated["kd"] / res.params["kd"]
    assert res.stderr_correlated["n"] / res.params["n"] < 0.1 * kd_rel  # only the halves' difference bends the lobe
    assert fit("modified_phong", wi, wo, f, u).stderr_correlated == {}
