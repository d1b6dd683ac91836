"""Type stub of the compiled HDR merge kernel (_merge_kernel.c); see rig.physics.hdr._merge_compiled."""

from collections.abc import Sequence

import numpy as np

def merge_rows(means: Sequence[np.ndarray], peaks: Sequence[np.ndarray], darks: Sequence[np.ndarray],
               thresholds: Sequence[float], inv_t: Sequence[float], a: Sequence[float], b: Sequence[float],
               c: Sequence[float], shortest: int, longest: int, passes: int, outputs: Sequence[np.ndarray | None],
               y0: int, y1: int) -> None: ...
