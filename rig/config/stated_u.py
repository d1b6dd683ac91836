"""Which calibration uncertainties a real rig's file leaves unstated (rig.config.rigfile.RigConfig).

A calibration whose certificate u is not in the rig file is used with u = 0: reported as such it would pass
for an exact calibration, so the keys are recorded (RigConfig.uncertainty_not_stated) and the report, the
monitor and dataset.json say "calibration u not stated: excluded" where the uncertainty is shown.
"""

from __future__ import annotations

from typing import Any


def states(section: Any, key: str) -> bool:
    """Whether a rig file's section (a mapping as read, or a model built in code) gives `key` itself."""
    if isinstance(section, dict):
        return section.get(key) is not None
    return key in getattr(section, "model_fields_set", ()) and getattr(section, key) is not None


def unstated_u(data: dict[str, Any]) -> tuple[str, ...]:
    """Key paths of the calibration u a rig file's data (before validation) does not state, with those it
    already lists (a rig configuration read back from a manifest): the camera's luminance coefficient
    (unless a calibration file gives it), the meter head's factor, each attenuating filter's transmission
    (an open position, transmission 1, has nothing to calibrate). Parts of the wrong shape are passed over:
    the validation that follows names them."""
    listed = data.get("uncertainty_not_stated", ())
    missing = [key for key in listed if isinstance(key, str)] if isinstance(listed, (list, tuple)) else []
    camera, meter = data.get("camera", {}), data.get("meter", {})
    if not states(camera, "calibration_u_rel") and not states(camera, "calibration_file"):
        missing.append("camera.calibration_u_rel")
    if not states(meter, "calibration_u_rel"):
        missing.append("meter.calibration_u_rel")
    attenuator = data.get("attenuator")
    filters = attenuator.get("filters", []) if isinstance(attenuator, dict) else getattr(attenuator, "filters", [])
    for f in filters if isinstance(filters, (list, tuple)) else ():
        if isinstance(f, dict):
            value = f
        elif hasattr(f, "model_dump"):
            value = f.model_dump(exclude_unset=True)
        else:
            continue
        if not states(f, "u_rel") and value.get("transmission", 1.0) != 1.0:
            missing.append(f"attenuator.filters[position {value.get('position')}].u_rel")
    return tuple(dict.fromkeys(missing))
