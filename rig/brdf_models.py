"""BRDF models, vectorised over arrays of directions (shared/reference/seeds-digest.md).

Every model takes unit vectors in the sample coordinate system (z = normal),
both pointing away from the surface, with shape (..., 3), and returns f_r in sr⁻¹.
A model is plain data about itself (parameter names, bounds, citation) plus a
pure `evaluate` function; `MODELS` is the registry campaign files refer to.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

Evaluate = Callable[..., np.ndarray]


def _dot(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    return np.sum(u * v, axis=-1)


def mirror_about_normal(w: np.ndarray) -> np.ndarray:
    """Mirror of w about z: i_s = 2(n·i)n − i."""
    return w * np.array([-1.0, -1.0, 1.0])


def cos_theta(w: np.ndarray) -> np.ndarray:
    return w[..., 2]


def phong_lobe(cos_angle: np.ndarray, n: float) -> np.ndarray:
    """Normalised Phong lobe (n+2)/(2π)·max(0, cos)^n."""
    return (n + 2.0) / (2.0 * np.pi) * np.maximum(cos_angle, 0.0) ** n


def lambert(wi: np.ndarray, wo: np.ndarray, *, kd: float) -> np.ndarray:
    """f = kd/π (kd = albedo)."""
    shape = np.broadcast_shapes(wi.shape, wo.shape)[:-1]
    return np.full(shape, kd / np.pi)


def modified_phong(wi: np.ndarray, wo: np.ndarray, *, kd: float, ks: float, n: float) -> np.ndarray:
    """Modified Phong (Lafortune), Spieringhs 2023 Eq. 3: kd/π + ks (n+2)/(2π) (i_s·o)^n."""
    return kd / np.pi + ks * phong_lobe(_dot(mirror_about_normal(wi), wo), n)


def retrophong(wi: np.ndarray, wo: np.ndarray, *, kd: float, n: float,
               k1: float, k2: float, k3: float, k4: float) -> np.ndarray:
    """RetroPhong, Spieringhs 2023 Eqs. 15, 17, 18.

    f = kd/π + ks(θi) (n+2)/(2π) (i_s·o)^n + kr(θi) (n+2)/(2π) (i·o)^n with
    kr(θi) = k1 (1 − cos θi) + k2 (retro lobe) and ks(θi) = k3 exp(k4 (1 − cos θi))
    (specular lobe). The paper's appendix code swaps the two names; the equations win.
    """
    one_minus_cos = 1.0 - cos_theta(wi)
    kr = k1 * one_minus_cos + k2
    ks = k3 * np.exp(k4 * one_minus_cos)
    return (kd / np.pi
            + ks * phong_lobe(_dot(mirror_about_normal(wi), wo), n)
            + kr * phong_lobe(_dot(wi, wo), n))


@dataclass(frozen=True)
class BrdfModel:
    name: str
    evaluate: Evaluate
    bounds: Mapping[str, tuple[float, float]]
    citation: str

    @property
    def param_names(self) -> tuple[str, ...]:
        return tuple(self.bounds)

    def __call__(self, wi: np.ndarray, wo: np.ndarray, params: Mapping[str, float]) -> np.ndarray:
        return self.evaluate(wi, wo, **params)


MODELS: dict[str, BrdfModel] = {
    m.name: m for m in (
        BrdfModel("lambert", lambert, {"kd": (0.0, 1.0)}, "Lambert"),
        BrdfModel("modified_phong", modified_phong,
                  {"kd": (0.0, 1.0), "ks": (0.0, 1.0), "n": (0.0, 1e5)},
                  "Lafortune 1994; Spieringhs et al. 2023 Eq. 3"),
        BrdfModel("retrophong", retrophong,
                  {"kd": (0.0, 1.0), "n": (0.0, 1e5), "k1": (0.0, 10.0), "k2": (0.0, 10.0),
                   "k3": (0.0, 10.0), "k4": (0.0, 50.0)},
                  "Spieringhs et al. 2023 Eqs. 15, 17, 18"),
    )
}


def get_model(name: str) -> BrdfModel:
    try:
        return MODELS[name]
    except KeyError:
        raise KeyError(f"unknown BRDF model {name!r}; known: {', '.join(sorted(MODELS))}") from None
