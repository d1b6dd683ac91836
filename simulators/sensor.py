"""EMVA 1288 linear camera model of the simulated luminance camera.

Signal chain per pixel: photo-electrons (Poisson, mean = luminance ×
responsivity × t × (1 + PRNU)) plus dark electrons (Poisson, mean =
(dark current + DSNU) × t), read noise (Gaussian, σd), full-well clipping,
gain K, black-level offset, rounding to integer DN and ADC clipping. The
photon-transfer relation σy² = K²σd² + σq² + K(μy − μy,dark) follows.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.config.rigfile import CameraConfig, SimulationConfig
from rig.core.values import Window

#: Poisson means are capped at this multiple of the full well: the pixel saturates
#: anyway, and numpy's Poisson sampler refuses astronomically large means.
SATURATION_GUARD = 2.0


def electrons(rng: np.random.Generator, mean_e: np.ndarray, read_noise_e: float,
              full_well_e: float) -> np.ndarray:
    """Collected charge in e⁻: Poisson(mean) + N(0, σd), clipped at the full well.

    Photo and dark electrons are independent Poisson variables, so their sum is
    drawn as one Poisson variable of the summed mean. Read noise is added
    before the full-well clip so that a saturated pixel reads exactly the
    saturation value, as on a camera whose ADC range matches its full well.
    """
    mean_e = np.minimum(mean_e, SATURATION_GUARD * full_well_e)
    charge = rng.poisson(mean_e).astype(float)
    if read_noise_e > 0:
        charge += rng.normal(0.0, read_noise_e, charge.shape)
    return np.minimum(charge, full_well_e, out=charge)


def digitise(electrons_e: np.ndarray, gain_dn_per_e: float, black_level_dn: float,
             bit_depth: int) -> np.ndarray:
    """DN = round(black level + K·e), clipped to the ADC range, as uint16."""
    dn = np.rint(black_level_dn + gain_dn_per_e * electrons_e)
    return np.clip(dn, 0, 2 ** bit_depth - 1).astype(np.uint16)


@dataclass(frozen=True)
class SensorModel:
    """A camera's configuration plus its full-sensor fixed patterns (H, W).

    `gain` is 1 + PRNU (relative photo response) and `dark_e_s` the dark
    current including DSNU (e⁻/s); neither is negative. Windows read slices of them.
    """

    camera: CameraConfig
    gain: np.ndarray
    dark_e_s: np.ndarray

    @classmethod
    def from_config(cls, camera: CameraConfig, sim: SimulationConfig,
                    rng: np.random.Generator) -> SensorModel:
        shape = (camera.height_px, camera.width_px)
        gain = np.maximum(1.0 + sim.prnu_rel * rng.standard_normal(shape), 0.0)
        dark = np.maximum(sim.dark_current_e_s + sim.dsnu_e_s * rng.standard_normal(shape), 0.0)
        return cls(camera, gain, dark)

    def mean_electrons(self, luminance_cd_m2: np.ndarray | float, exposure_s: float,
                       window: Window) -> np.ndarray:
        """Expected photo + dark electrons (height, width) of the window."""
        rows = slice(window.y0, window.y0 + window.height)
        cols = slice(window.x0, window.x0 + window.width)
        photo = (self.camera.responsivity_e_per_cd_m2_s * exposure_s) * luminance_cd_m2
        return photo * self.gain[rows, cols] + self.dark_e_s[rows, cols] * exposure_s

    def read(self, rng: np.random.Generator, luminance_cd_m2: np.ndarray | float,
             exposure_s: float, window: Window) -> np.ndarray:
        """One noisy raw frame (uint16, (height, width)); luminance 0 gives a dark frame."""
        cam = self.camera
        charge = electrons(rng, self.mean_electrons(luminance_cd_m2, exposure_s, window),
                           cam.read_noise_e, cam.full_well_e)
        return digitise(charge, cam.gain_dn_per_e, cam.black_level_dn, cam.bit_depth)
