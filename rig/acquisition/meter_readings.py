"""E⊥ from a batch of meter readings, as the engine records it: the estimate and its `illuminance` event.

A batch with a reading in the dark is no E⊥: a non-positive mean, or any underload (the meter saw less than
its range resolves, `IlluminanceReading.floor_a`). Dividing luminances by such an E⊥ would give BRDF values
of pure noise, so the batch is refused with a DeviceError naming the figures: the engine then looks for a
lamp that went out (and pauses for it) or ends the run with that message. A lab expects the same: light
on the detector, or no measurement.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from rig.config.rigfile import MeterConfig
from rig.core.errors import DeviceError
from rig.core.values import IlluminanceReading
from rig.physics.illuminance import IlluminanceEstimate, estimate, underload_u


def illuminance_of(readings: Sequence[IlluminanceReading], rig_time_s: float,
                   meter: MeterConfig) -> tuple[IlluminanceEstimate, dict[str, Any]]:
    """E⊥ of the readings (with the meter's repeatability, calibration and range uncertainties) and the fields
    of its `illuminance` event; DeviceError when the meter sees no light."""
    dark = [(r, r.floor_a) for r in readings if r.floor_a is not None]
    if dark:
        r, floor = dark[0]
        u_lx = underload_u(floor) * r.calibration_lx_per_a
        raise DeviceError("meter", f"{len(dark)} of {len(readings)} readings below the meter's floor (underload: "
                                   f"less than {floor:g} A on range {r.range_index}, E⊥ taken as "
                                   f"{r.illuminance_lx:.2g} ± {u_lx:.2g} lx): no light on the detector")
    values = np.array([r.illuminance_lx for r in readings])
    if not values.mean() > 0:
        raise DeviceError("meter", f"E⊥ reads {values.mean():g} lx (photocurrent {readings[0].photocurrent_a:g} A):"
                                   " no light on the detector")
    range_u = [0.0 if r.range_index is None else meter.range_u_rel[r.range_index] for r in readings]
    est = estimate(values, rig_time_s, meter.repeatability_rel, meter.calibration_u_rel, np.array(range_u))
    fields = {"illuminance_normal_lx": est.value_lx, "u_lx": est.u_lx, "readings": est.n,
              "photocurrent_a": float(np.mean([r.photocurrent_a for r in readings])),
              "calibration_lx_per_a": readings[0].calibration_lx_per_a, "rig_time_s": est.rig_time_s}
    return est, fields
