"""The capture path of a run, chosen once: `capturer_for` is the one place that asks what kind of camera the
rig has.

A camera that delivers raw frames gets a `RawCapturer` (rig.acquisition.capture: HDR merge, dark frames);
one that calibrates its own pictures (`CalibratedLuminanceCamera`, the LMK) a `CalibratedCapturer`
(rig.acquisition.calibrated_capture). Either takes a point with `acquire()`, which returns an acquisition
that knows whether its ROI clipped and how to reduce itself to a `PointCapture` (`reduce()`, no camera I/O:
the engine starts the next move in between; the interfaces: rig.acquisition.capturing). On a rig with a
filter wheel the chosen capturer is wrapped, once, in an `AttenuatingCapturer` (rig.acquisition.attenuation)
with the same interface: the engine never asks whether there is a wheel. The
capturer receives the run's clock: it times each point, ages dark frames and lets the lamp supply's
keep-alives run between blocking camera calls (rig.acquisition.tending).
"""

from __future__ import annotations

from rig.acquisition.attenuation import AttenuatingCapturer, Attenuation
from rig.acquisition.calibrated_capture import CalibratedCapturer
from rig.acquisition.capture import RawCapturer
from rig.acquisition.capturing import Capturer
from rig.config.capture import CaptureSettings
from rig.core.clock import Clock
from rig.drivers.interfaces import CalibratedLuminanceCamera, LuminanceCamera


def capturer_for(camera: LuminanceCamera, settings: CaptureSettings, clock: Clock | None = None,
                 attenuation: Attenuation | None = None) -> Capturer:
    """The capturer of `camera` with `settings`, on the run's `clock` (None: no rig clock; points are timed by
    their exposures, and dark frames cannot age: dark_max_age_s must be None); through the filter wheel's
    `attenuation` if the rig has one (rig.acquisition.attenuation.attenuation_for)."""
    capturer: Capturer
    if isinstance(camera, CalibratedLuminanceCamera):
        capturer = CalibratedCapturer(camera, settings, clock)
    else:
        capturer = RawCapturer(camera, settings, clock)
    return capturer if attenuation is None else AttenuatingCapturer(capturer, attenuation)
