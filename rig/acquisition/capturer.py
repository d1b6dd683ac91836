"""The capture path of a run, chosen once: `capturer_for` is the one place that asks what kind of camera the
rig has.

A camera that delivers raw frames gets a `RawCapturer` (rig.acquisition.capture: HDR merge, dark frames);
one that calibrates its own pictures (`CalibratedLuminanceCamera`, the LMK) a `CalibratedCapturer`
(rig.acquisition.calibrated_capture). Either takes a point with `acquire()`, which returns an acquisition
that knows whether its ROI clipped (for the filter wheel, rig.acquisition.attenuation) and how to reduce
itself to a `PointCapture` (`reduce()`, no camera I/O: the engine starts the next move in between). The
capturer receives the run's clock: it times each point, ages dark frames and lets the lamp supply's
keep-alives run between blocking camera calls (rig.acquisition.tending).
"""

from __future__ import annotations

from typing import Protocol

from rig.acquisition.calibrated_capture import CalibratedCapturer
from rig.acquisition.capture import RawCapturer
from rig.config.capture import CaptureSettings
from rig.core.clock import Clock
from rig.core.values import PointCapture, SensorInfo, Window
from rig.drivers.interfaces import CalibratedLuminanceCamera, LuminanceCamera


class PointAcquisition(Protocol):
    """What one point took from the camera, before its numbers are computed."""

    @property
    def clipped(self) -> bool:
        """Whether ROI pixels saturated in every exposure (their luminance is only a lower bound)."""

    def reduce(self) -> PointCapture:
        """The point's ROI statistics, flags and uncertainty components (and its image when saved)."""


class Capturer(Protocol):
    """Takes the points of a run with one camera, the same way each time."""

    @property
    def sensor(self) -> SensorInfo: ...

    @property
    def roi(self) -> Window:
        """The central ROI whose luminance is the point's measurement."""

    def acquire(self) -> PointAcquisition:
        """Expose the current view as its ROI needs."""

    def probe(self, exposure_s: float) -> tuple[float, float]:
        """One exposure of the ROI alone: its peak as a fraction of the usable range, and the exposure realised."""


def capturer_for(camera: LuminanceCamera, settings: CaptureSettings, clock: Clock | None = None) -> Capturer:
    """The capturer of `camera` with `settings`, on the run's `clock` (None: no rig clock; points are timed by
    their exposures, and dark frames cannot age: dark_max_age_s must be None)."""
    if isinstance(camera, CalibratedLuminanceCamera):
        return CalibratedCapturer(camera, settings, clock)
    return RawCapturer(camera, settings, clock)
