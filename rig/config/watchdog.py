"""What the lamp supply's watchdog allows one blocking device exchange, where the campaign decides it.

The supply switches the lamp off when no command reaches it for `lamp.watchdog_s` (W). Its keep-alive
(rig.drivers.delta_sm) is due every W/4 of rig time and skips a feed right after a command, never two
in a row, so it speaks at least every W/2 wherever the rig clock gives it the chance: in every sleep,
and after every blocking meter reading or camera picture (rig.acquisition.tending). What it cannot
cover is one exchange that blocks by itself: the supply then hears nothing for up to W/2 plus that
exchange, so one exchange may block for at most W/2 (BLOCKING_FRACTION).

The rig file bounds what depends on it alone (a meter reading, a vendor camera's single picture:
rig.config.rigfile). What depends on the campaign as well is checked here, before anything starts: a
camera that takes a whole HDR series in one call (a CalibratedLuminanceCamera: the LMK's
`iHighDynPic`) blocks for every exposure from `camera.max_exposure_s` down to `camera.min_exposure_s`,
successive ones the campaign's bracket factor apart, and a read-out of each (at worst: LabSoft picks
which it needs). A raw camera's HDR series, dark frames and a meter's readings are runs of exchanges,
fed between them, and need no bound beyond the rig file's.
"""

from __future__ import annotations

import importlib
import inspect
import math

from rig.config.capture import CaptureSettings
from rig.config.rigdevices import SERVED_CAMERA
from rig.config.rigfile import RigConfig
from rig.drivers.interfaces import CalibratedLuminanceCamera
from rig.drivers.registry import driver_class

#: The share of `lamp.watchdog_s` one blocking exchange may last (module docstring).
BLOCKING_FRACTION = 0.5


def hdr_picture_s(max_exposure_s: float, min_exposure_s: float, factor: float, readout_s: float) -> tuple[float, int]:
    """Longest time and number of pictures of one HDR picture: every exposure from the longest down to the
    shortest, `factor` apart, with a read-out each."""
    pictures = math.floor(math.log(max_exposure_s / min_exposure_s, factor) + 1e-9) + 1
    exposures = max_exposure_s * (1 - factor ** -pictures) / (1 - 1 / factor)
    return exposures + pictures * readout_s, pictures


def _one_call_hdr(driver: str) -> bool:
    """Whether camera `driver` takes an HDR series in one call (a CalibratedLuminanceCamera). A driver that
    does not load is not judged here: rig.devices.check_devices refuses it, naming why."""
    if driver in ("simulated", SERVED_CAMERA):
        return False
    try:
        if driver.startswith("python:"):
            module, _, name = driver.removeprefix("python:").partition(":")
            cls = getattr(importlib.import_module(module), name)
        else:
            cls = driver_class("camera", driver)
    except Exception:      # ImportError, LookupError, or whatever a plug-in's module raises on import
        return False
    return inspect.isclass(cls) and issubclass(cls, CalibratedLuminanceCamera)


def watchdog_problems(capture: CaptureSettings, rig: RigConfig) -> list[str]:
    """Why the campaign's `capture` on `rig` would block the lamp's keep-alive beyond what the watchdog allows
    (module docstring); empty if it does not."""
    if capture.mode == "adaptive":
        hdr, stops_key, stops = capture.max_exposures > 1, "capture.bracket_stops", capture.bracket_stops
    else:
        hdr, stops_key, stops = capture.bracket_count > 1, "capture.bracket_step_stops", capture.bracket_step_stops
    if not hdr or not _one_call_hdr(rig.devices.camera.driver):
        return []
    cam, budget_s = rig.camera, BLOCKING_FRACTION * rig.lamp.watchdog_s
    picture_s, pictures = hdr_picture_s(cam.max_exposure_s, cam.min_exposure_s, 2.0 ** stops, cam.readout_s)
    if picture_s <= budget_s:
        return []
    count_key = "capture.max_exposures" if capture.mode == "adaptive" else "capture.bracket_count"
    return [f"keys 'capture.mode' ({capture.mode}), '{count_key}', '{stops_key}' with 'camera.max_exposure_s', "
            f"'camera.min_exposure_s', 'camera.readout_s' and 'lamp.watchdog_s': camera driver "
            f"{rig.devices.camera.driver!r} takes an HDR picture in one blocking call, up to {pictures} exposures "
            f"from {cam.max_exposure_s:g} s down to {cam.min_exposure_s:g} s, {2.0 ** stops:g}× apart, with a "
            f"{cam.readout_s:g} s read-out each: {picture_s:.3g} s, more than the {budget_s:g} s budget of one "
            f"blocking exchange (half of lamp.watchdog_s {rig.lamp.watchdog_s:g} s: the supply's keep-alive cannot "
            f"run meanwhile and the lamp would go out); lower camera.max_exposure_s, raise {stops_key} or "
            f"lamp.watchdog_s, or allow one exposure ({count_key}: 1)"]
