"""Type stub of the compiled rays on the lit sample (_view_kernel.c), used by rig.simulators.camera.lit_view."""

import numpy as np

def lit_rays(rows: np.ndarray, cols: np.ndarray, height: float, origin_x: float, origin_z: float, radius2: float,
             start_x: float, start_y: float, lit: np.ndarray, xy: np.ndarray, wo: np.ndarray) -> int: ...
