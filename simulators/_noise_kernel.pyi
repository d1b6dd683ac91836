"""Type stub of the compiled value noise (_noise_kernel.c), used by rig.simulators.texture."""

from collections.abc import Sequence

import numpy as np

def value_noise(coords: Sequence[np.ndarray], contrast: float, seed: int, out: np.ndarray,
                start: int, stop: int) -> None: ...
