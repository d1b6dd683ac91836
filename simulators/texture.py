"""Procedural reflectance texture of the simulated sample.

A multiplicative, seeded value noise in sample coordinates (metres): lattice
values on a square grid of pitch `grain_m` are hashed from their integer
coordinates (so the texture is infinite and nothing big is stored), drawn from
a log-normal law with mean 1 and standard deviation `contrast` (positive for
any contrast), and blended with smoothstep weights. The weights sum to one, so
the expected texture is exactly 1 everywhere and the ground-truth BRDF is the
texture-free model; the spatial standard deviation is contrast · 26/35
because blending averages neighbouring lattice values.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.special import ndtri

from rig.rigconfig import SimulationConfig

_MASK64 = (1 << 64) - 1


def mix64(z: np.ndarray) -> np.ndarray:
    """SplitMix64 finaliser: a bijective avalanche of uint64 values."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def hash_uniform(ix: np.ndarray, iy: np.ndarray, seed: int) -> np.ndarray:
    """Uniform numbers in the open interval (0, 1), one per integer lattice node and seed."""
    key = np.uint64(int(mix64(np.array([seed & _MASK64], np.uint64))[0]))
    ix = np.asarray(ix, np.int64).view(np.uint64)
    iy = np.asarray(iy, np.int64).view(np.uint64)
    with np.errstate(over="ignore"):
        h = mix64(mix64(ix ^ key) ^ iy)
    return ((h >> np.uint64(11)).astype(float) + 0.5) * 2.0 ** -53


def lognormal_unit_mean(u: np.ndarray, contrast: float) -> np.ndarray:
    """The u-quantiles of the log-normal law with mean 1 and standard deviation `contrast`."""
    sigma = np.sqrt(np.log1p(contrast ** 2))
    return np.exp(sigma * ndtri(u) - sigma ** 2 / 2)


def smoothstep(t: np.ndarray) -> np.ndarray:
    """3t² − 2t³: C¹ blending weight on [0, 1], so the texture has no visible lattice creases."""
    return t * t * (3.0 - 2.0 * t)


@dataclass(frozen=True)
class ValueNoiseTexture:
    """Reflectance factor of the sample at sample coordinates (x, y) in metres."""

    contrast: float
    grain_m: float
    seed: int

    @classmethod
    def from_config(cls, sim: SimulationConfig) -> "ValueNoiseTexture":
        return cls(contrast=sim.texture_contrast, grain_m=sim.texture_grain_m, seed=sim.seed)

    def lattice(self, ix: np.ndarray, iy: np.ndarray) -> np.ndarray:
        """Values at integer lattice nodes (mean 1, standard deviation `contrast`)."""
        return lognormal_unit_mean(hash_uniform(ix, iy, self.seed), self.contrast)

    def corner_values(self, ix: np.ndarray, iy: np.ndarray) -> list[np.ndarray]:
        """Lattice values at (ix, iy), (ix+1, iy), (ix, iy+1), (ix+1, iy+1).

        Points of one image are dense on the lattice, so hashing the covering
        block of nodes once is cheaper than hashing four nodes per point.
        """
        offsets = ((0, 0), (1, 0), (0, 1), (1, 1))
        if ix.size:
            x0, y0 = ix.min(), iy.min()
            nx, ny = int(ix.max() - x0) + 2, int(iy.max() - y0) + 2       # Python ints: no overflow
            if nx * ny <= ix.size:
                table = self.lattice(x0 + np.arange(nx)[None, :], y0 + np.arange(ny)[:, None]).ravel()
                base = (iy - y0) * nx + (ix - x0)
                return [table.take(base + dy * nx + dx) for dx, dy in offsets]
        return [self.lattice(ix + dx, iy + dy) for dx, dy in offsets]

    def __call__(self, x_m: np.ndarray, y_m: np.ndarray) -> np.ndarray:
        """Texture values at sample coordinates x, y (m, finite, broadcast together)."""
        gx, gy = np.broadcast_arrays(np.asarray(x_m, float) / self.grain_m,
                                     np.asarray(y_m, float) / self.grain_m)
        fx, fy = np.floor(gx), np.floor(gy)
        wx, wy = smoothstep(gx - fx), smoothstep(gy - fy)
        v00, v10, v01, v11 = self.corner_values(fx.astype(np.int64), fy.astype(np.int64))
        return (1 - wy) * ((1 - wx) * v00 + wx * v10) + wy * ((1 - wx) * v01 + wx * v11)
