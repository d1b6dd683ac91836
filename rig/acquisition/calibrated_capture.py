"""Capture of one measurement point with a camera that delivers calibrated luminance (TechnoTeam LMK):
the calibrated path, `CalibratedCapturer` (chosen by rig.acquisition.capturer).

Such a camera (`CalibratedLuminanceCamera`) applies its own calibration, subtracts
its own dark signal and merges its own exposures, so this path takes no dark
frames and merges nothing: it asks for one picture, reads the window around the
ROI and reduces the ROI with the same pure statistics as the raw path
(`rig.physics.roi`), into the same `PointCapture`.

The picture (from the campaign's `CaptureSettings`):

- a high-dynamic-range picture when the settings allow more than one exposure
  (`adaptive` with max_exposures > 1, `fixed_bracket` with bracket_count > 1): the
  camera picks exposures between the sensor's longest and shortest, successive
  ones 2**bracket_stops (`adaptive`) or 2**bracket_step_stops (`fixed_bracket`) apart;
- otherwise a single picture, metered like the raw path: from probe_exposure_s,
  the exposure that puts the picture's peak load at target_fraction of the range,
  shortened by bracket_stops while the camera reports overflow, retaken at most
  METERING_STEPS times (rig.acquisition.metering). The peak is the whole picture's (the camera reports no
  other), not the ROI's.

frames_per_exposure, target_snr and max_frames have no effect: the camera averages
nothing here. What is not known and how it is set:

- u_noise and u_dark are 0 (unknown, not absent): the camera gives no per-pixel
  variance, so the spread of the ROI's block means, which holds noise and texture,
  is all reported as u_texture; u_luminance (block spread ⊕ calibration) is whole.
- `roi_saturated` where the camera marks overflowed ROI pixels; a camera that only
  reports an overflowed fraction of the picture (the LMK) cannot say where, so any
  overflow flags the point, and saturated_fraction is that picture fraction.
- exposures_s are what the camera reports (the LMK: longest, shortest and count,
  the ones between assumed evenly spaced in log time); capture_time_s is rig time
  on the clock, else the summed exposures.
- an acquisition never counts as clipped: such a camera has its own attenuation (the LMK's
  filters), so a filter wheel stays on its clearest filter (rig.acquisition.attenuation).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from rig.acquisition.metering import KEEP_STOPS, METERING_STEPS, MIN_LOAD, point_windows
from rig.acquisition.tending import TendedCalibratedCamera
from rig.config.capture import CaptureSettings
from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.core.values import LuminanceImage, PointCapture, SensorInfo, Window
from rig.drivers.interfaces import CalibratedLuminanceCamera
from rig.physics.roi import point_flags, roi_statistics


@dataclass(frozen=True)
class CalibratedAcquisition:
    """What one point took from a calibrated camera; `reduce()` turns it into numbers."""

    settings: CaptureSettings
    device: str                         # the camera's identity, for errors found in the reduction
    calibration_u_rel: float
    roi: Window
    image: LuminanceImage               # the picture kept (of the window read)
    n_frames: int                       # pictures taken, metering included
    capture_time_s: float

    @property
    def clipped(self) -> bool:
        """Never: such a camera has its own attenuation (module docstring)."""
        return False

    def reduce(self) -> PointCapture:
        """ROI statistics and flags of a calibrated picture; no camera I/O (module docstring)."""
        image, settings = self.image, self.settings
        in_roi = image.window.inner(self.roi)
        roi_pixels = np.asarray(image.pixels_cd_m2[in_roi], dtype=float)
        if not np.all(np.isfinite(roi_pixels)):
            raise DeviceError(self.device, f"returned {np.sum(~np.isfinite(roi_pixels))} non-finite luminance "
                                           f"values in the ROI {self.roi}")
        stats = roi_statistics(roi_pixels, np.zeros_like(roi_pixels))
        if image.saturated is not None:
            saturated_fraction = float(np.mean(image.saturated[in_roi]))
        else:
            saturated_fraction = image.overflow_fraction
        return PointCapture(
            **stats.capture_fields(),
            u_luminance_cd_m2=stats.u_luminance(self.calibration_u_rel),
            exposures_s=image.exposures_s,
            saturated_fraction=saturated_fraction,
            flags=point_flags(stats, settings.min_snr, saturated_fraction > 0),
            image_cd_m2=image.pixels_cd_m2 if settings.full_frame else None,
            roi_window=self.roi,
            n_frames=self.n_frames,
            u_noise_cd_m2=0.0,
            u_dark_cd_m2=0.0,
            capture_time_s=self.capture_time_s,
            n_darks=0,
        )


def _single_exposure(camera: CalibratedLuminanceCamera, window: Window, sensor: SensorInfo,
                     settings: CaptureSettings) -> tuple[LuminanceImage, int]:
    """The metered single picture (module docstring) and the number of pictures taken."""
    limits = sensor.min_exposure_s, sensor.max_exposure_s
    t = float(np.clip(settings.probe_exposure_s, *limits))
    for taken in range(1, METERING_STEPS + 1):
        image = camera.capture_luminance(t, window)
        if image.peak_load is None:
            raise DeviceError(camera.identity(), "reported no peak load: a single picture cannot be metered")
        if image.overflow_fraction > 0 or image.peak_load >= 1.0:
            t_next = float(np.clip(t * 2.0 ** -settings.bracket_stops, *limits))
        else:
            t_next = float(np.clip(t * settings.target_fraction / max(image.peak_load, MIN_LOAD), *limits))
            if abs(np.log2(t_next / t)) <= KEEP_STOPS:
                return image, taken
        if t_next == t:
            return image, taken          # at the end of the sensor's range: nothing better to take
        t = t_next
    return image, METERING_STEPS


class CalibratedCapturer:
    """Captures the points of a run with a camera that calibrates its own pictures (module docstring); each
    point is timed on the run's `clock`, whose due keep-alives run after every picture
    (rig.acquisition.tending)."""

    def __init__(self, camera: CalibratedLuminanceCamera, settings: CaptureSettings, clock: Clock | None = None):
        self.camera: CalibratedLuminanceCamera = TendedCalibratedCamera(camera, clock) if clock else camera
        self.settings, self.clock = settings, clock
        self.roi, self.window = point_windows(camera, settings)

    @property
    def sensor(self) -> SensorInfo:
        return self.camera.sensor

    def acquire(self) -> CalibratedAcquisition:
        """Take the point's picture (module docstring)."""
        camera, settings, clock, roi, window = self.camera, self.settings, self.clock, self.roi, self.window
        start_s = clock.now() if clock else 0.0
        sensor = camera.sensor
        exposures = settings.max_exposures if settings.mode == "adaptive" else settings.bracket_count
        if exposures > 1:
            stops = settings.bracket_stops if settings.mode == "adaptive" else settings.bracket_step_stops
            image = camera.capture_hdr_luminance(sensor.max_exposure_s, sensor.min_exposure_s, 2.0 ** stops, window)
            taken = len(image.exposures_s)
        else:
            image, taken = _single_exposure(camera, window, sensor, settings)
        if image.pixels_cd_m2.shape != (image.window.height, image.window.width):
            raise DeviceError(camera.identity(),
                              f"returned a {image.pixels_cd_m2.shape} picture for window {image.window}")
        try:
            image.window.inner(roi)
        except ValueError:
            raise DeviceError(camera.identity(), f"returned window {image.window} for window {window}") from None
        return CalibratedAcquisition(
            settings=settings, device=camera.identity(), calibration_u_rel=sensor.calibration_u_rel, roi=roi,
            image=image, n_frames=taken,
            capture_time_s=clock.now() - start_s if clock else float(sum(image.exposures_s)))

    def probe(self, exposure_s: float) -> tuple[float, float]:
        """One picture of the ROI alone at exposure_s: its peak load (fraction of the range), and the exposure
        realised. The attenuator asks only after a clipped acquisition, which this camera never returns."""
        image = self.camera.capture_luminance(exposure_s, self.roi)
        if image.peak_load is None:
            raise DeviceError(self.camera.identity(), "reported no peak load: a picture cannot be metered")
        return image.peak_load, image.exposures_s[0]
