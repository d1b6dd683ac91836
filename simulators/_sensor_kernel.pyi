"""Type stub of the compiled sensor read-out (_sensor_kernel.c); see rig.simulators.sensor.SensorModel.read."""

import numpy as np

def read_rows(out: np.ndarray, response: np.ndarray, dark_e_s: np.ndarray, luminance: np.ndarray | float,
              exposure_s: float, photo_scale: float, read_noise_e: float, full_well_e: float,
              saturation_guard: float, max_skewness: float, nonlinearity_rel: float, gain_dn_per_e: float,
              black_level_dn: float, bit_depth: int, seed: int, y0: int, y1: int) -> None: ...
def standard_normal(seed: int, out: np.ndarray) -> None: ...
def poisson(seed: int, mean: float, out: np.ndarray) -> None: ...
