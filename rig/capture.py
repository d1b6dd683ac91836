"""HDR capture of one measurement point with a `LuminanceCamera`.

The only module that drives the camera. It chooses the exposures the ROI needs
(Hasinoff et al. 2010: scene-adapted exposure sets beat fixed brackets), takes
them with cached dark frames, and hands the raw data to the pure physics in
`rig.hdr` (merge) and `rig.roi` (ROI statistics).

Exposure strategy: a probe exposure meters the ROI; the main exposure puts the
ROI's peak raw signal at `target_fraction` of the usable range, re-metering if
the probe saw mostly noise (lengthening up to the sensor's longest exposure).
If the probe saturates in the ROI its peak is unknown, so the probe itself is
the main exposure; while ROI pixels saturate in the shortest exposure so far,
shorter exposures `bracket_stops` apart are added, up to `max_exposures`.
Exposures saturated over the whole window are then left out of the merge.
Exposure times lie on a 1/6-stop ladder so that dark frames are reused from
point to point.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drivers.interfaces import DeviceError, Frame, LuminanceCamera, SensorInfo, Window
from rig.hdr import merge_exposures, saturation_threshold_dn
from rig.roi import BLOCK_PX, roi_statistics

#: Metering frames taken at most before the main exposure is accepted.
MAX_METERING_STEPS = 4
#: A metered exposure within this many stops of the ideal one is kept rather than retaken.
KEEP_TOLERANCE_STOPS = 0.5
#: Peak signals below this (DN) are treated as this, so an unlit ROI asks for the longest exposure.
MIN_PEAK_DN = 1.0


@dataclass(frozen=True)
class CaptureSettings:
    """How one point is exposed; built from the campaign file."""

    roi_px: int = 70                  # side of the central square ROI (px)
    probe_exposure_s: float = 0.002   # first, metering exposure
    target_fraction: float = 0.7      # ROI peak above black level / usable range
    bracket_stops: float = 2.0        # spacing of added shorter exposures
    max_exposures: int = 5            # exposures merged at most
    frames_per_exposure: int = 1      # frames averaged per exposure
    min_snr: float = 10.0             # ROI mean / its uncertainty below this: `low_signal`
    full_frame: bool = False          # read, merge and return the whole sensor
    window_margin_px: int = 0         # extra pixels read around the ROI

    def __post_init__(self):
        checks = {
            "roi_px": (self.roi_px >= 2 * BLOCK_PX, f"an integer ≥ {2 * BLOCK_PX} (two {BLOCK_PX}-px blocks)"),
            "probe_exposure_s": (self.probe_exposure_s > 0, "> 0"),
            "target_fraction": (0 < self.target_fraction < 1, "between 0 and 1 (exclusive)"),
            "bracket_stops": (self.bracket_stops >= 0.5, "≥ 0.5"),
            "max_exposures": (self.max_exposures >= 1, "an integer ≥ 1"),
            "frames_per_exposure": (self.frames_per_exposure >= 1, "an integer ≥ 1"),
            "min_snr": (self.min_snr >= 0, "≥ 0"),
            "window_margin_px": (self.window_margin_px >= 0, "an integer ≥ 0"),
        }
        for name, (ok, allowed) in checks.items():
            if not ok:
                raise ValueError(f"capture setting {name} = {getattr(self, name)!r}: must be {allowed}")


@dataclass(frozen=True)
class PointCapture:
    """Result of `capture_point`: the ROI luminance and how it was obtained."""

    luminance_cd_m2: float
    u_luminance_cd_m2: float           # block-based ROI uncertainty ⊕ calibration
    roi_std_cd_m2: float               # pixel standard deviation inside the ROI
    exposures_s: tuple[float, ...]     # realised exposure times merged
    saturated_fraction: float          # of ROI pixels, in the longest merged exposure
    flags: tuple[str, ...]             # `low_signal`, `roi_saturated`
    image_cd_m2: np.ndarray | None     # whole merged image when full_frame
    roi_window: Window                 # in sensor coordinates
    n_frames: int                      # raw frames taken, darks excluded


class DarkFrameCache:
    """Dark frames keyed by (exposure time, window), taken when first needed.

    Dark signal depends on exposure time and sensor temperature, not on the
    scene, so one dark serves every point exposed on the same rung of the
    exposure ladder until `invalidate` (e.g. on a re-take schedule).
    """

    def __init__(self, frames_per_dark: int = 1, steps_per_stop: int = 6):
        if frames_per_dark < 1 or steps_per_stop < 1:
            raise ValueError("frames_per_dark and steps_per_stop must be ≥ 1")
        self.frames_per_dark = frames_per_dark
        self.steps_per_stop = steps_per_stop
        self.n_taken = 0                  # dark frames taken so far
        self._darks: dict[tuple[float, Window], np.ndarray] = {}

    def snap(self, exposure_s: float, sensor: SensorInfo) -> float:
        """Nearest exposure time (s) on the ladder, clamped to the sensor's range."""
        rung = np.round(np.log2(exposure_s) * self.steps_per_stop) / self.steps_per_stop
        return float(np.clip(2.0 ** rung, sensor.min_exposure_s, sensor.max_exposure_s))

    def get(self, camera: LuminanceCamera, exposure_s: float, window: Window) -> np.ndarray:
        """Stack (m, H, W) of raw dark frames for an exposure time on the ladder."""
        if exposure_s != self.snap(exposure_s, camera.sensor):
            raise ValueError(f"exposure {exposure_s} s is not on the dark-frame ladder; use snap()")
        key = (exposure_s, window)
        if key not in self._darks:
            self._darks[key] = np.stack([_pixels(camera, camera.capture_dark(exposure_s, window), window)
                                         for _ in range(self.frames_per_dark)])
            self.n_taken += self.frames_per_dark
        return self._darks[key]

    def invalidate(self) -> None:
        """Forget all darks, so that the next points take fresh ones."""
        self._darks.clear()

    def __len__(self) -> int:
        return len(self._darks)


def _pixels(camera: LuminanceCamera, frame: Frame, window: Window) -> np.ndarray:
    """The frame's pixels, after checking the camera read the window asked for."""
    if frame.pixels_dn.shape != (window.height, window.width):
        raise DeviceError(camera.identity(), f"returned a {frame.pixels_dn.shape} frame for window {window}")
    return frame.pixels_dn


def _grown(window: Window, margin_px: int, sensor: SensorInfo) -> Window:
    """`window` grown by `margin_px` on every side, clipped to the sensor."""
    x0, y0 = max(window.x0 - margin_px, 0), max(window.y0 - margin_px, 0)
    x1 = min(window.x0 + window.width + margin_px, sensor.width_px)
    y1 = min(window.y0 + window.height + margin_px, sensor.height_px)
    return Window(x0, y0, x1 - x0, y1 - y0)


def capture_point(camera: LuminanceCamera, settings: CaptureSettings, darks: DarkFrameCache) -> PointCapture:
    """Expose, merge and reduce the ROI of the current view (see the module docstring)."""
    sensor = camera.sensor
    if settings.roi_px > min(sensor.width_px, sensor.height_px):
        raise ValueError(f"roi_px {settings.roi_px} exceeds the {sensor.width_px}×{sensor.height_px} sensor")
    roi = Window.centred(sensor.width_px, sensor.height_px, settings.roi_px, settings.roi_px)
    window = camera.full_window() if settings.full_frame else _grown(roi, settings.window_margin_px, sensor)
    in_roi = window.inner(roi)
    threshold = saturation_threshold_dn(sensor)
    target_dn = settings.target_fraction * (threshold - sensor.black_level_dn)
    shots: dict[float, list[np.ndarray]] = {}
    realised: dict[float, list[float]] = {}

    def shoot(exposure_s: float, count: int) -> np.ndarray:
        """All frames (≥ count, H, W) at exposure_s, taking only those still missing."""
        frames = shots.setdefault(exposure_s, [])
        while len(frames) < count:
            frame = camera.capture(exposure_s, window)
            frames.append(_pixels(camera, frame, window))
            realised.setdefault(exposure_s, []).append(frame.exposure_s)
        return np.stack(frames)

    def roi_saturates(exposure_s: float) -> bool:
        return bool(np.any(shoot(exposure_s, 1)[(slice(None),) + in_roi] >= threshold))

    # Metering: the black level stands in for the dark frame, which only shifts the
    # peak by the dark current and saves darks of exposures that are not kept.
    t = darks.snap(settings.probe_exposure_s, sensor)
    for _ in range(MAX_METERING_STEPS):
        raw = shoot(t, 1)[0][in_roi]
        if np.any(raw >= threshold):
            break          # peak unknown: keep t, the bracket below adds shorter exposures
        peak_dn = float(raw.max()) - sensor.black_level_dn
        t_next = darks.snap(t * target_dn / max(peak_dn, MIN_PEAK_DN), sensor)
        if t_next <= 2 * t:
            if abs(np.log2(t_next / t)) > KEEP_TOLERANCE_STOPS:
                t = t_next
            break
        t = t_next         # under-exposed by over a stop: the peak was mostly noise, meter again

    exposures = [t]
    shoot(t, settings.frames_per_exposure)
    while (roi_saturates(exposures[-1]) and len(exposures) < settings.max_exposures
           and exposures[-1] > sensor.min_exposure_s):
        shorter = darks.snap(max(exposures[-1] * 2.0 ** -settings.bracket_stops, sensor.min_exposure_s), sensor)
        exposures.append(shorter)
        shoot(shorter, settings.frames_per_exposure)

    # An exposure saturated everywhere adds nothing; keep at least the shortest.
    useful = [e for e in exposures if not np.all(np.any(shoot(e, 1) >= threshold, axis=0))] or [exposures[-1]]
    exposures_s = tuple(float(np.mean(realised[e])) for e in useful)
    merged = merge_exposures([shoot(e, settings.frames_per_exposure) for e in useful],
                             [darks.get(camera, e, window) for e in useful], exposures_s, sensor)
    cal = sensor.calibration_cd_m2_per_dn_s
    luminance = merged.rate_dn_s * cal
    stats = roi_statistics(luminance[in_roi], merged.var_rate[in_roi] * cal ** 2)

    flags = []
    if stats.mean <= settings.min_snr * stats.u_mean:
        flags.append("low_signal")
    if np.any(merged.clipped[in_roi]):
        flags.append("roi_saturated")
    return PointCapture(
        luminance_cd_m2=stats.mean,
        u_luminance_cd_m2=float(np.hypot(stats.u_mean, sensor.calibration_u_rel * stats.mean)),
        roi_std_cd_m2=stats.std,
        exposures_s=exposures_s,
        saturated_fraction=float(np.mean(merged.saturated[in_roi])),
        flags=tuple(flags),
        image_cd_m2=luminance if settings.full_frame else None,
        roi_window=roi,
        n_frames=sum(len(frames) for frames in shots.values()),
    )
