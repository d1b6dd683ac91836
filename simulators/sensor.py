"""EMVA 1288 linear camera model of the simulated luminance camera.

Signal chain per pixel: photo-electrons (Poisson, mean = luminance ×
responsivity × t × (1 + PRNU)) plus dark electrons (Poisson, mean =
(dark current + DSNU) × t), read noise (Gaussian, σd), full-well clipping,
gain K, black-level offset, rounding to integer DN and ADC clipping. The
photon-transfer relation σy² = K²σd² + σq² + K(μy − μy,dark) follows.

Two truths for `rig calibrate camera` to recover: the lens's natural vignetting
(cos⁴ of each pixel's field angle in the pinhole model; the central ROI of a long
lens loses under 1e-4) scales the photo-electrons, and an optional nonlinearity of
the charge conversion (`simulation.nonlinearity_rel`, 0 by default) bends the response.

SensorModel.read runs the whole chain (mean image, electrons' hybrid rule, nonlinearity,
digitise; float32 as here) in the compiled kernel `_sensor_kernel.c`: its own ziggurat
normals and exact Poisson sampler, one band of rows per CPU, every row's random numbers
seeded from (one 64-bit draw of the caller's Generator per frame, the row), so a frame does
not depend on the number of CPUs. Installed without a C compiler, the numpy functions below
do it: the same statistics, another random stream.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, partial

import numpy as np

from rig.config.rigfile import CameraConfig, SimulationConfig
from rig.core.bands import run_in_bands
from rig.core.values import Window

try:
    from rig.simulators import _sensor_kernel
except ImportError:            # installed without a C compiler: the numpy functions below do it all
    _sensor_kernel = None  # type: ignore[assignment]

#: Poisson means are capped at this multiple of the full well: the pixel saturates
#: anyway, and numpy's Poisson sampler refuses astronomically large means.
SATURATION_GUARD = 2.0
#: Largest skewness of Poisson(λ) + N(0, σd²) at which the charge is drawn as a normal (see electrons).
NORMAL_MAX_SKEWNESS = 0.02
#: Luminance arrays the compiled kernel reads as they are; others are converted to float64 first.
_KERNEL_LUMINANCE = (np.dtype(np.float64), np.dtype(np.float32))


def electrons(rng: np.random.Generator, mean_e: np.ndarray, read_noise_e: float,
              full_well_e: float) -> np.ndarray:
    """Collected charge in e⁻ (float32): Poisson(mean) + N(0, σd), clipped at the full well.

    Photo and dark electrons are independent Poisson variables, so their sum is
    drawn as one Poisson variable of the summed mean. Read noise is added
    before the full-well clip so that a saturated pixel reads exactly the
    saturation value, as on a camera whose ADC range matches its full well.

    Where it is indistinguishable, the charge is drawn as one normal N(λ, λ + σd²)
    (float32, 3× faster than numpy's Poisson sampler on a full frame): it has the
    exact mean and variance of Poisson(λ) + N(0, σd²), and the sum's higher cumulants
    differ from the normal's (zero) by λ each, so the largest error is the skewness
    γ = λ/(λ + σd²)^{3/2}; pixels with γ ≤ NORMAL_MAX_SKEWNESS take the normal. Large
    counts (γ ≈ 1/√λ) qualify, and small ones only under read noise much wider than
    the Poisson steps (σd = 8 e⁻: λ ≤ 10 or λ ≥ 2500); without read noise every
    count below 2500 e⁻ is drawn exactly, in between too.
    """
    mean_e = np.minimum(mean_e, SATURATION_GUARD * full_well_e, dtype=np.float32)
    var_e2 = mean_e + np.float32(read_noise_e ** 2)
    cube = np.square(var_e2)
    cube *= var_e2
    cube *= NORMAL_MAX_SKEWNESS ** 2
    exact = np.square(mean_e) > cube                                            # γ² > limit²
    charge = rng.standard_normal(mean_e.shape, dtype=np.float32)
    charge *= np.sqrt(var_e2, out=var_e2)
    charge += mean_e
    if exact.any():
        poisson = rng.poisson(mean_e[exact]).astype(np.float32)
        if read_noise_e > 0:
            poisson += rng.normal(0.0, read_noise_e, poisson.shape).astype(np.float32)
        charge[exact] = poisson
    return np.minimum(charge, full_well_e, out=charge)


def natural_vignetting(camera: CameraConfig) -> np.ndarray:
    """cos⁴ of each pixel centre's angle to the optical axis (H, W): the natural vignetting of a pinhole
    lens. Pixel centres are at +0.5 as in rig.physics.optics."""
    pitch_mm = camera.pixel_pitch_um * 1e-3
    y, x = np.mgrid[0:camera.height_px, 0:camera.width_px].astype(float)
    r2_mm2 = (((x + 0.5 - camera.width_px / 2) * pitch_mm) ** 2 + ((y + 0.5 - camera.height_px / 2) * pitch_mm) ** 2)
    return (camera.focal_length_mm ** 2 / (camera.focal_length_mm ** 2 + r2_mm2)) ** 2


def convert_nonlinear(charge_e: np.ndarray, nonlinearity_rel: float, full_well_e: float) -> np.ndarray:
    """Charge seen through a quadratic conversion e·(1 − β(1 − e/FW)), β = nonlinearity_rel: the response
    falls short by β·e near zero and by nothing at the full well, so saturation stays where it was."""
    return charge_e * (1.0 - nonlinearity_rel * (1.0 - charge_e / full_well_e))


def digitise(electrons_e: np.ndarray, gain_dn_per_e: float, black_level_dn: float,
             bit_depth: int) -> np.ndarray:
    """DN = round(black level + K·e), clipped to the ADC range, as uint16."""
    dn = np.multiply(electrons_e, gain_dn_per_e, dtype=np.result_type(electrons_e, np.float32))
    dn += black_level_dn
    np.rint(dn, out=dn)
    return np.clip(dn, 0, 2 ** bit_depth - 1, out=dn).astype(np.uint16)


@dataclass(frozen=True)
class SensorModel:
    """A camera's configuration plus its full-sensor fixed patterns (H, W).

    `gain` is 1 + PRNU (relative photo response), `illumination` the lens's relative
    illumination (cos⁴ fall-off, 1 on the axis) and `dark_e_s` the dark current
    including DSNU (e⁻/s); none is negative. Windows read slices of them.
    """

    camera: CameraConfig
    gain: np.ndarray
    dark_e_s: np.ndarray
    illumination: np.ndarray
    nonlinearity_rel: float = 0.0

    @classmethod
    def from_config(cls, camera: CameraConfig, sim: SimulationConfig,
                    rng: np.random.Generator) -> SensorModel:
        shape = (camera.height_px, camera.width_px)
        gain = np.maximum(1.0 + sim.prnu_rel * rng.standard_normal(shape), 0.0)
        dark = np.maximum(sim.dark_current_e_s + sim.dsnu_e_s * rng.standard_normal(shape), 0.0)
        return cls(camera, gain, dark, natural_vignetting(camera), sim.nonlinearity_rel)

    @cached_property
    def _response(self) -> tuple[np.ndarray, np.ndarray]:
        """gain · illumination and dark_e_s in float32: what mean_electrons multiplies by, once."""
        return (self.gain * self.illumination).astype(np.float32), self.dark_e_s.astype(np.float32)

    def mean_electrons(self, luminance_cd_m2: np.ndarray | float, exposure_s: float,
                       window: Window) -> np.ndarray:
        """Expected photo + dark electrons (height, width) of the window (float32)."""
        rows = slice(window.y0, window.y0 + window.height)
        cols = slice(window.x0, window.x0 + window.width)
        response, dark_e_s = (a[rows, cols] for a in self._response)
        mean = np.multiply(dark_e_s, exposure_s, dtype=np.float32)
        mean += np.multiply(luminance_cd_m2, self.camera.responsivity_e_per_cd_m2_s * exposure_s,
                            dtype=np.float32) * response
        return mean

    def read(self, rng: np.random.Generator, luminance_cd_m2: np.ndarray | float,
             exposure_s: float, window: Window) -> np.ndarray:
        """One noisy raw frame (uint16, (height, width)); luminance 0 gives a dark frame."""
        if _sensor_kernel is not None:
            return self._read_compiled(rng, luminance_cd_m2, exposure_s, window)
        cam = self.camera
        charge = electrons(rng, self.mean_electrons(luminance_cd_m2, exposure_s, window),
                           cam.read_noise_e, cam.full_well_e)
        if self.nonlinearity_rel:
            charge = convert_nonlinear(charge, self.nonlinearity_rel, cam.full_well_e)
        return digitise(charge, cam.gain_dn_per_e, cam.black_level_dn, cam.bit_depth)

    def _read_compiled(self, rng: np.random.Generator, luminance_cd_m2: np.ndarray | float,
                       exposure_s: float, window: Window) -> np.ndarray:
        """read by the compiled kernel (_sensor_kernel.c), one band of rows per CPU (rig.core.bands): the
        frame's seed is one 64-bit draw from rng, each row's stream is derived from it and the row."""
        cam = self.camera
        shape = (window.height, window.width)
        rows = slice(window.y0, window.y0 + window.height)
        cols = slice(window.x0, window.x0 + window.width)
        response, dark_e_s = (a[rows, cols] for a in self._response)
        luminance: np.ndarray | float
        if np.ndim(luminance_cd_m2) == 0:
            luminance = float(luminance_cd_m2)
        else:
            luminance = np.asarray(luminance_cd_m2)
            if luminance.dtype not in _KERNEL_LUMINANCE or not luminance.dtype.isnative:
                luminance = luminance.astype(np.float64)
            luminance = np.broadcast_to(luminance, shape)
        out = np.empty(shape, np.uint16)
        seed = int(rng.integers(0, 2 ** 64, dtype=np.uint64))
        run_in_bands(partial(
            _sensor_kernel.read_rows, out, response, dark_e_s, luminance, exposure_s,
            cam.responsivity_e_per_cd_m2_s * exposure_s, cam.read_noise_e, cam.full_well_e, SATURATION_GUARD,
            NORMAL_MAX_SKEWNESS, self.nonlinearity_rel, cam.gain_dn_per_e, cam.black_level_dn, cam.bit_depth,
            seed), *shape)
        return out

