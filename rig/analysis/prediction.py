"""What every BRDF predictor returns, and the interface the exports and planning code against.

A predictor gives the BRDF and its standard uncertainty at arbitrary directions (degrees at the edge),
and says where it extrapolates beyond the measured domain. rig.analysis.predict builds them from a
dataset (a fitted model with its covariance, or an interpolant of the measurements).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike


@dataclass(frozen=True)
class Prediction:
    """Arrays of one shape (the broadcast shape of the four angles)."""

    brdf_per_sr: np.ndarray
    u_brdf_per_sr: np.ndarray       # standard uncertainty (k = 1)
    extrapolated: np.ndarray        # bool: outside the measured domain (the value is a model's guess there)


class Predictor(Protocol):
    #: How it predicts, in a few words for reports: e.g. "model retrophong (fit, covariance)".
    method: str

    def predict(self, theta_i_deg: ArrayLike, phi_i_deg: ArrayLike, theta_o_deg: ArrayLike,
                phi_o_deg: ArrayLike) -> Prediction:
        """The BRDF at (θi, φi, θo, φo), degrees, SCS (docs/geometry.md); arrays broadcast together."""
        ...
