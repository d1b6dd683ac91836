"""Procedural reflectance texture of the simulated sample: static grains times directional glints.

Both factors are multiplicative, seeded value noise: lattice values are hashed
from their integer coordinates (so the texture is infinite and nothing big is
stored), drawn from a log-normal law with mean 1 and standard deviation
`contrast` (positive for any contrast), and blended with smoothstep weights.

- The static factor lives on a square lattice of pitch `grain_m` in sample
  coordinates (metres): every view of the sample sees the same pattern.
- The glint factor (glass beads, aggregate) lives on a 4-D lattice: pitch
  `grain_m` in (x, y) and `angle_rad` in the half vector h = normalize(ωi + ωo)
  projected on the sample plane (h_x, h_y). Each direction cell hashes its own
  spatial pattern, so the ROI mean changes from view to view: the correlation
  of two views' ROI means is ½ when their half vectors are 0.6 pitch apart and
  exactly 0 beyond 2 pitches (they share no lattice node). Near the normal a
  pitch of h_x is a rotation of h by `angle_rad`, i.e. of ωo by about twice that.

The blending weights sum to one, so each factor's expected value is exactly 1
at every point and direction. The factors hash different numbers of
coordinates (2 and 4), so their lattice values are independent and the
expected texture, the product of the two expectations, is exactly 1: the
ground-truth BRDF is the texture-free model. Blending averages neighbouring
lattice values: per lattice dimension the standard deviation shrinks by
√(26/35), e.g. contrast · 26/35 for the static factor.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.special import ndtri

from rig.config.rigfile import SimulationConfig
from rig.core.bands import run_in_bands
from rig.physics.geometry import dot

try:
    from rig.simulators import _noise_kernel
except ImportError:            # installed without a C compiler: value_noise runs in numpy
    _noise_kernel = None  # type: ignore[assignment]

_MASK64 = (1 << 64) - 1
#: Axes the compiled value noise takes (the glint's four at most).
_KERNEL_MAX_AXES = 4


def mix64(z: np.ndarray) -> np.ndarray:
    """SplitMix64 finaliser: a bijective avalanche of uint64 values."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


def hash_uniform(*nodes: np.ndarray, seed: int) -> np.ndarray:
    """Uniform numbers in the open interval (0, 1), one per integer lattice node (broadcast) and seed."""
    h: np.ndarray = np.asarray(mix64(np.array([seed & _MASK64], np.uint64))[0])
    with np.errstate(over="ignore"):
        for n in nodes:
            h = mix64(h ^ np.asarray(n, np.int64).view(np.uint64))
    return ((h >> np.uint64(11)).astype(float) + 0.5) * 2.0 ** -53


def lognormal_unit_mean(u: np.ndarray, contrast: float) -> np.ndarray:
    """The u-quantiles of the log-normal law with mean 1 and standard deviation `contrast`."""
    sigma = np.sqrt(np.log1p(contrast ** 2))
    return np.exp(sigma * ndtri(u) - sigma ** 2 / 2)


def smoothstep(t: np.ndarray) -> np.ndarray:
    """3t² − 2t³: C¹ blending weight on [0, 1], so the texture has no visible lattice creases."""
    return t * t * (3.0 - 2.0 * t)


def corner_values(lattice: Callable[..., np.ndarray], cells: Sequence[np.ndarray]) -> list[np.ndarray]:
    """Lattice values at the 2ⁿ corners of each point's cell (n = len(cells), int64 arrays of one shape).

    Corner c lies +1 along axis k where bit k of c is set. Points of one image
    are dense on the lattice, so when the covering block of nodes is smaller
    than 2ⁿ nodes per point, hashing it once is cheaper than hashing per point.
    """
    bits = [[(c >> k) & 1 for k in range(len(cells))] for c in range(2 ** len(cells))]
    if cells[0].size:
        lo = [int(c.min()) for c in cells]                               # Python ints: no overflow
        shape = [int(c.max()) - low + 2 for c, low in zip(cells, lo)]
        if math.prod(shape) <= len(bits) * cells[0].size:
            table = lattice(*np.ix_(*(low + np.arange(n) for low, n in zip(lo, shape)))).ravel()
            strides = [math.prod(shape[k + 1:]) for k in range(len(shape))]
            base = sum((c - low) * s for c, low, s in zip(cells, lo, strides))
            return [table.take(base + sum(b * s for b, s in zip(corner, strides))) for corner in bits]
    return [lattice(*(c + b for c, b in zip(cells, corner))) for corner in bits]


def blend(corners: list[np.ndarray], weights: Sequence[np.ndarray]) -> np.ndarray:
    """Multilinear blend of 2ⁿ corner values (ordered as in corner_values) with per-axis weights."""
    for w in weights:                  # pairs (2j, 2j+1) differ along the axis being blended away
        corners = [_lerp(a, b, w) for a, b in zip(corners[::2], corners[1::2])]
    return corners[0]


def _lerp(a: np.ndarray, b: np.ndarray, w: np.ndarray) -> np.ndarray:
    """a + w (b − a), with one temporary: blending dominates the cost of a textured render."""
    d = b - a
    d *= w
    d += a
    return d


def noise_lattice(nodes: Sequence[np.ndarray], contrast: float, seed: int) -> np.ndarray:
    """Values at integer lattice nodes (broadcast): log-normal, mean 1, standard deviation `contrast`."""
    return lognormal_unit_mean(hash_uniform(*nodes, seed=seed), contrast)


def value_noise(coords: Sequence[np.ndarray], contrast: float, seed: int) -> np.ndarray:
    """Value noise with mean 1 at finite lattice coordinates (any number of axes, broadcast together).

    With the compiled kernel (_noise_kernel.c, 1 to 4 axes) the points are split into one run per CPU
    (rig.core.bands); its values are those of the numpy code below, which runs where it was not built.
    """
    coords = np.broadcast_arrays(*(np.asarray(c, float) for c in coords))
    if _noise_kernel is not None and 1 <= len(coords) <= _KERNEL_MAX_AXES:
        flat = [c.reshape(-1) for c in coords]
        out = np.empty(flat[0].size)
        run_in_bands(functools.partial(_noise_kernel.value_noise, flat, contrast, seed & _MASK64, out), out.size, 1)
        return out.reshape(coords[0].shape)
    cells = [np.floor(c) for c in coords]
    weights = [smoothstep(c - f) for c, f in zip(coords, cells)]
    corners = corner_values(lambda *nodes: noise_lattice(nodes, contrast, seed),
                            [f.astype(np.int64) for f in cells])
    return blend(corners, weights)


@dataclass(frozen=True)
class ValueNoiseTexture:
    """Static reflectance factor of the sample at sample coordinates (x, y) in metres."""

    contrast: float
    grain_m: float
    seed: int

    @classmethod
    def from_config(cls, sim: SimulationConfig) -> ValueNoiseTexture:
        return cls(contrast=sim.texture_contrast, grain_m=sim.texture_grain_m, seed=sim.seed)

    def lattice(self, ix: np.ndarray, iy: np.ndarray) -> np.ndarray:
        """Values at integer lattice nodes (mean 1, standard deviation `contrast`)."""
        return noise_lattice((ix, iy), self.contrast, self.seed)

    def __call__(self, x_m: np.ndarray, y_m: np.ndarray) -> np.ndarray:
        """Texture values at sample coordinates x, y (m, finite, broadcast together)."""
        return value_noise((np.asarray(x_m, float) / self.grain_m, np.asarray(y_m, float) / self.grain_m),
                           self.contrast, self.seed)


@dataclass(frozen=True)
class GlintTexture:
    """Direction-dependent reflectance factor: value noise over the half vector's (h_x, h_y) and (x, y)."""

    contrast: float
    grain_m: float
    angle_rad: float
    seed: int

    @classmethod
    def from_config(cls, sim: SimulationConfig) -> GlintTexture:
        return cls(contrast=sim.glint_contrast, grain_m=sim.glint_grain_m,
                   angle_rad=math.radians(sim.glint_angle_deg), seed=sim.seed)

    def __call__(self, x_m: np.ndarray, y_m: np.ndarray, wi: np.ndarray, wo: np.ndarray) -> np.ndarray:
        """Glint factor at sample coordinates x, y (m) for SCS unit vectors wi, wo (..., 3), all broadcast."""
        h = np.asarray(wi, float) + np.asarray(wo, float)
        scale = 1.0 / (self.angle_rad * np.sqrt(dot(h, h)))            # normalise h, then to lattice units
        return value_noise((h[..., 0] * scale, h[..., 1] * scale,
                            np.asarray(x_m, float) / self.grain_m, np.asarray(y_m, float) / self.grain_m),
                           self.contrast, self.seed)
