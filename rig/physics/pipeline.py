"""From ROI luminance and illuminance to BRDF with a GUM uncertainty.

Pure, vectorised numpy. f_r = L / (E⊥ cos θi) with E(θi) = E⊥ cos θi on the
sample plane; the relative standard uncertainty combines, uncorrelated,
u_rel(f)² = u_rel(L)² + u_rel(E⊥)² + (tan θi · u_θ)², u_θ in radians. Towards
grazing incidence cos θi → 0 and both f_r and its angle term blow up, so
these are flagged and kept finite instead of producing inf/NaN that would
break CSV readers and fits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

#: Smallest cos θi used; at and beyond it (θi ≈ 90°) the values are finite but meaningless.
COS_MIN = 1e-6
GRAZING_LIMIT_DEG = 88.0


@dataclass(frozen=True)
class BrdfResult:
    """Arrays broadcast from the inputs of `brdf_from_luminance`."""

    brdf_per_sr: np.ndarray
    u_brdf_per_sr: np.ndarray        # combined standard uncertainty (k = 1)
    illuminance_lx: np.ndarray       # E(θi) = E⊥ cos θi used
    grazing_incidence: np.ndarray    # bool: θi ≥ grazing limit, or cos θi ≤ COS_MIN


def brdf_from_luminance(luminance_cd_m2: ArrayLike, u_luminance_cd_m2: ArrayLike,
                        illuminance_normal_lx: ArrayLike, u_illuminance_normal_lx: ArrayLike,
                        theta_i_deg: ArrayLike, u_theta_deg: ArrayLike,
                        grazing_limit_deg: float = GRAZING_LIMIT_DEG) -> BrdfResult:
    """BRDF (sr⁻¹) and its standard uncertainty from ROI luminance and E⊥.

    All arguments broadcast against each other. The uncertainty is computed in
    absolute form, u(f)² = (u_L/E)² + (f u_E⊥/E⊥)² + (f tan θi u_θ)², which equals
    the relative form but stays defined for L = 0 (an unlit ROI); `hypot` keeps
    the squares from overflowing at grazing incidence. E⊥ must be
    positive: a zero reading is a meter fault, not a measurement.
    """
    lum, u_lum, e_normal, u_e_normal, theta_deg, u_theta = np.broadcast_arrays(
        *(np.asarray(a, dtype=float) for a in (luminance_cd_m2, u_luminance_cd_m2,
                                               illuminance_normal_lx, u_illuminance_normal_lx,
                                               theta_i_deg, u_theta_deg)))
    if np.any(~(e_normal > 0)):
        raise ValueError("illuminance_normal_lx must be positive")
    theta = np.deg2rad(theta_deg)
    cos_raw = np.cos(theta)
    grazing = (cos_raw <= COS_MIN) | (np.abs(theta_deg) >= grazing_limit_deg)
    cos_i = np.maximum(cos_raw, COS_MIN)
    tan_i = np.abs(np.sin(theta)) / cos_i
    illuminance = e_normal * cos_i
    brdf = lum / illuminance
    u_brdf = np.hypot(np.hypot(u_lum / illuminance, brdf * u_e_normal / e_normal),
                      brdf * tan_i * np.deg2rad(u_theta))
    return BrdfResult(brdf_per_sr=brdf, u_brdf_per_sr=u_brdf, illuminance_lx=illuminance,
                      grazing_incidence=grazing)
