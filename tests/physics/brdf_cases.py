"""The papers' fitted parameters and the formulas computed by hand that tests/physics/test_brdf_models.py and
test_brdf_properties.py compare rig.physics.brdf_models with (sources: the top of test_brdf_models.py)."""

import numpy as np

from rig.physics.geometry import sph_to_vec

RM1 = {"kd": 0.620, "n": 24.0, "k1": 0.158, "k2": 0.0415, "k3": 0.00133, "k4": 5.47}

#: Spieringhs 2023 Tables 3, 6 and 7: RM1, RM2, RM3 per model.
PAPER_FITS = {
    "retrophong": [RM1,
                   {"kd": 0.594, "n": 24.0, "k1": 0.0696, "k2": 0.0733, "k3": 6.58e-05, "k4": 8.74},
                   {"kd": 0.701, "n": 68.0, "k1": 0.184, "k2": 1.53e-12, "k3": 0.00570, "k4": 3.40}],
    "oren_nayar": [{"roughness": 0.865, "albedo": 0.268}, {"roughness": 0.705, "albedo": 0.275},
                   {"roughness": 1.26, "albedo": 0.470}],
    "beckmann_retro": [{"kd": 0.796, "alpha": 8.20, "r0": 0.995}, {"kd": 0.822, "alpha": 9.36, "r0": 0.993},
                       {"kd": 0.996, "alpha": 1.61e3, "r0": 1.00}],
    "blinn_retro": [{"kd": 0.919, "alpha_b": 2.77e3, "alpha_r": 7.91e3},
                    {"kd": 0.881, "alpha_b": 2.50e3, "alpha_r": 7.10e3},
                    {"kd": 0.993, "alpha_b": 6.72e3, "alpha_r": 1.65e4}],
    "abc_retro": [{"kd": 0.534, "r0": 0.0472, "a_b": 1.82, "b_b": 13.5, "c_b": 1.51,
                   "a_r": 1.02, "b_r": 0.0775, "c_r": 6.97},
                  {"kd": 0.0303, "r0": 0.140, "a_b": 1.59, "b_b": 32.6, "c_b": 1.08,
                   "a_r": 1.19, "b_r": 0.00779, "c_r": 0.0179},
                  {"kd": 0.747, "r0": 0.00466, "a_b": 6.66, "b_b": 37.8, "c_b": 0.710,
                   "a_r": 3.58, "b_r": 22.9, "c_r": 0.729}],
}

RECIPROCAL = {"lambert", "modified_phong", "oren_nayar", "beckmann_retro", "blinn_retro", "abc_retro",
              "ggx", "mrm", "mrm_diffuse"}

#: Parameter sets under which each energy-conserving claim must hold (modified Phong: kd + ks ≤ 1).
ENERGY_GRIDS = {
    "lambert": [{"kd": 1.0}],
    "modified_phong": [{"kd": kd, "ks": 1.0 - kd, "n": n} for kd in (0.0, 0.5) for n in (0.1, 1.0, 10.0, 300.0)],
    "ggx": [{"roughness": r, "f0": f0} for r in (0.23, 0.48, 0.77, 1.0) for f0 in (0.04, 1.0)],
    "mrm": [{"roughness": r, "f0": f0} for r in (0.23, 0.48, 0.77, 1.0) for f0 in (0.04, 1.0)],
}


def d(theta_deg, phi_deg):
    return sph_to_vec(np.radians(theta_deg), np.radians(phi_deg))


def unit(v):
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def schlick_by_hand(u, r0):
    return r0 + (1 - r0) * (1 - u) ** 5


def beckmann_by_hand(c, alpha):          # Spieringhs 2023 Eq. 6
    return np.exp((c**2 - 1) / (alpha**2 * c**2)) / (np.pi * alpha**2 * c**4)


def ggx_d_by_hand(c, alpha):
    return alpha**2 / (np.pi * (c**2 * (alpha**2 - 1) + 1) ** 2)


def smith_lambda_by_hand(c, alpha):      # Heitz 2014 Eq. 72: (−1 + √(1 + α² tan²θ))/2
    return (-1 + np.sqrt(1 + alpha**2 * (1 - c**2) / c**2)) / 2


def cook_torrance_g_by_hand(i, o, h):
    n_h, n_i, n_o, o_h = h[2], i[2], o[2], np.dot(o, h)
    return min(1.0, 2 * n_h * n_o / o_h, 2 * n_h * n_i / o_h)
