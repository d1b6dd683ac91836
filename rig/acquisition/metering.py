"""Where a point is metered and read, and how long metering goes on: the one home of both, for the raw
path (rig.acquisition.capture) and the calibrated one (rig.acquisition.calibrated_capture).

The ROI is the central `roi_px` square of the sensor; the camera reads the ROI grown by
`window_margin_px` (clipped to the sensor), or the whole sensor when images are saved (`full_frame`).
Metering probes always read the grown ROI: nothing outside it decides the exposure.

Both paths meter alike: from `probe_exposure_s`, the exposure that puts the peak at `target_fraction`
of the range, retaken at most METERING_STEPS times; a metered exposure within KEEP_STOPS of the ideal
one is kept rather than retaken. A peak below the floor (MIN_PEAK_DN of raw signal, MIN_LOAD of a
calibrated camera's range) counts as the floor, so an unlit ROI asks for the longest exposure.
"""

from __future__ import annotations

from rig.config.capture import CaptureSettings
from rig.core.values import Window
from rig.drivers.interfaces import LuminanceCamera

#: Metering exposures (raw frames or single calibrated pictures) taken at most for one point.
METERING_STEPS = 4
#: A metered exposure within this many stops of the ideal one is kept rather than retaken.
KEEP_STOPS = 0.5
#: Raw peak signals below this (DN above black level) are treated as this.
MIN_PEAK_DN = 1.0
#: Peak loads of a calibrated camera (fraction of its range) below this are treated as this.
MIN_LOAD = 1e-3


def metering_window(camera: LuminanceCamera, settings: CaptureSettings) -> Window:
    """The window metering probes read: the ROI grown by window_margin_px, clipped to the sensor."""
    roi = point_roi(camera, settings)
    sensor, margin = camera.sensor, settings.window_margin_px
    x0, y0 = max(roi.x0 - margin, 0), max(roi.y0 - margin, 0)
    x1 = min(roi.x0 + roi.width + margin, sensor.width_px)
    y1 = min(roi.y0 + roi.height + margin, sensor.height_px)
    return Window(x0, y0, x1 - x0, y1 - y0)


def point_roi(camera: LuminanceCamera, settings: CaptureSettings) -> Window:
    """The central roi_px square of the camera's sensor (ValueError if it does not fit)."""
    sensor = camera.sensor
    if settings.roi_px > min(sensor.width_px, sensor.height_px):
        raise ValueError(f"roi_px {settings.roi_px} exceeds the {sensor.width_px}×{sensor.height_px} sensor")
    return Window.centred(sensor.width_px, sensor.height_px, settings.roi_px, settings.roi_px)


def point_windows(camera: LuminanceCamera, settings: CaptureSettings) -> tuple[Window, Window]:
    """The central ROI and the window the camera reads for the point's exposures: the metering window, or
    the whole sensor when full_frame."""
    roi = point_roi(camera, settings)
    return roi, camera.full_window() if settings.full_frame else metering_window(camera, settings)
