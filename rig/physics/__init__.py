"""The physics and the metrology of the measurement, pure numpy (no device, no file, no configuration).

Owns: `geometry` (angle conventions and goniometer kinematics, docs/geometry.md), `optics`, `footprint`,
`hdr` (the noise-optimal HDR merge; its pixel loop also in C, _merge_kernel.c), `roi`, `illuminance` (E⊥
from the meter's readings, drift and the measurement equation f_r = L / (E⊥ cos θi), `brdf_from_luminance`),
`budget` (the GUM uncertainty budget), `brdf_models`, `peak_fit`, `camera_calibration` (the EMVA 1288 reductions),
`charuco_board` and `goniometer_fit` (the geometry calibration's board and model).
May import: rig.core only; rig.drivers beside it in the same layer is off limits.
"""
