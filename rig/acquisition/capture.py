"""HDR capture of one measurement point with a `LuminanceCamera`.

The only module that drives the camera (a camera delivering calibrated
luminance is handed to `rig.acquisition.calibrated_capture`). It chooses the exposures the ROI needs
(Hasinoff et al. 2010: scene-adapted exposure sets beat fixed brackets), takes
them with cached dark frames, and hands the raw data to the pure physics in
`rig.physics.hdr` (merge) and `rig.physics.roi` (ROI statistics).

Metering (both modes): a probe exposure meters the ROI; the metered exposure
puts the ROI's peak raw signal at `target_fraction` of the usable range,
re-metering if the probe saw mostly noise (lengthening up to the sensor's
longest exposure). If the probe saturates in the ROI its peak is unknown, so
the probe itself is the metered exposure.

`adaptive` mode: the metered exposure, plus — while ROI pixels saturate in the
shortest exposure so far — shorter exposures `bracket_stops` apart, up to
`max_exposures`; exposures saturated over the whole merged region are left out.
Then frames are added to every exposure (frame averaging) until the camera-noise
SNR of the ROI mean reaches `target_snr` or `max_frames` frames per exposure;
each dark stack is topped up to as many frames as its exposure has, so that the
dark's noise, which averaging light frames cannot reduce, keeps pace. Averaging
that could not lift that SNR even to `min_snr` is not attempted: the point stays
`low_signal` whatever it costs. A bright, ordinary ROI needs the probe and one
exposure.

`fixed_bracket` mode (the baseline, like a vendor HDR mode): `bracket_count`
exposures `bracket_step_stops` apart centred on the metered exposure, all
merged (the merge excludes saturated samples), `frames_per_exposure` frames each.

Exposure times lie on a 1/6-stop ladder so that dark frames are reused from
point to point. Only the ROI is merged unless `full_frame` (images are saved);
the camera reads only a window around the ROI, or, if it cannot, the frame it
returns is cropped. With `full_frame` the metering probes still read only that
window; the exposures kept are read whole, and merged whole for the saved image
only: the point's numbers come from the ROI's merge either way.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from rig.acquisition.calibrated_capture import (
    CalibratedAcquisition,
    acquire_calibrated,
    point_windows,
    reduce_calibrated,
)
from rig.config.capture import CaptureSettings
from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.core.values import Frame, PointCapture, SensorInfo, Window
from rig.drivers.interfaces import CalibratedLuminanceCamera, LuminanceCamera
from rig.physics.camera_calibration import CalibratedSensorInfo
from rig.physics.hdr import HdrMerge, merge_exposures, merged_rate, saturation_threshold_dn
from rig.physics.roi import mean_noise, point_flags, roi_statistics

#: Metering frames taken at most before the metered exposure is accepted.
MAX_METERING_STEPS = 4
#: A metered exposure within this many stops of the ideal one is kept rather than retaken.
KEEP_TOLERANCE_STOPS = 0.5
#: Peak signals below this (DN) are treated as this, so an unlit ROI asks for the longest exposure.
MIN_PEAK_DN = 1.0

def _pixels(camera: LuminanceCamera, frame: Frame, window: Window) -> np.ndarray:
    """`window`'s pixels of a frame; a camera that cannot read windows returns a larger one."""
    if frame.pixels_dn.shape != (frame.window.height, frame.window.width):
        raise DeviceError(camera.identity(), f"returned a {frame.pixels_dn.shape} frame for window {frame.window}")
    try:
        return frame.pixels_dn[frame.window.inner(window)]
    except ValueError:
        raise DeviceError(camera.identity(), f"returned window {frame.window} for window {window}") from None


class DarkFrameCache:
    """Dark frames keyed by (exposure time, window), taken when first needed.

    Dark signal depends on exposure time and sensor temperature, not on the
    scene, so one dark serves every point exposed on the same rung of the
    exposure ladder while it is valid: younger than the `max_age_s` asked for,
    on `clock` (the rig's; it also times `capture_point`), and not dropped by
    `invalidate` (call it when the sensor temperature has changed).
    """

    def __init__(self, frames_per_dark: int = 1, steps_per_stop: int = 6, clock: Clock | None = None):
        if frames_per_dark < 1 or steps_per_stop < 1:
            raise ValueError("frames_per_dark and steps_per_stop must be ≥ 1")
        self.frames_per_dark = frames_per_dark
        self.steps_per_stop = steps_per_stop
        self.clock = clock
        self.n_taken = 0                  # dark frames taken so far
        self.exposed_s = 0.0              # their summed exposure time
        self._darks: dict[tuple[float, Window], tuple[float, FrameStack]] = {}

    def snap(self, exposure_s: float, sensor: SensorInfo) -> float:
        """Nearest exposure time (s) on the ladder, clamped to the sensor's range.

        Clamping before rounding too makes snap idempotent when a range limit is
        not a rung (the ladder then ends on the rung nearest the limit).
        """
        limits = sensor.min_exposure_s, sensor.max_exposure_s
        rung = np.round(np.log2(np.clip(exposure_s, *limits)) * self.steps_per_stop) / self.steps_per_stop
        return float(np.clip(2.0 ** rung, *limits))

    def get(self, camera: LuminanceCamera, exposure_s: float, window: Window, frames: int = 1,
            max_age_s: float | None = None) -> np.ndarray:
        """Stack (m, H, W), m ≥ max(frames_per_dark, frames), of raw darks for a ladder exposure.

        A stack taken more than `max_age_s` ago is re-taken; a short one is
        topped up and keeps the age of its first frame.
        """
        if exposure_s != self.snap(exposure_s, camera.sensor):
            raise ValueError(f"exposure {exposure_s} s is not on the dark-frame ladder; use snap()")
        if max_age_s is not None and self.clock is None:
            raise ValueError("dark frames can only age on a clock: give the DarkFrameCache the rig clock")
        now = self.clock.now() if self.clock else 0.0
        key = (exposure_s, window)
        taken_s, stack = self._darks.get(key, (now, FrameStack()))
        if max_age_s is not None and now - taken_s > max_age_s:
            taken_s, stack = now, FrameStack()
        while len(stack) < max(self.frames_per_dark, frames):
            frame = camera.capture_dark(exposure_s, window)
            stack.append(_pixels(camera, frame, window))
            self.n_taken += 1
            self.exposed_s += frame.exposure_s
        self._darks[key] = (taken_s, stack)
        return stack.array()

    def invalidate(self) -> None:
        """Forget all darks, so that the next points take fresh ones."""
        self._darks.clear()

    def __len__(self) -> int:
        return len(self._darks)


class FrameStack:
    """Frames of one exposure, added one by one and read as one (n, H, W) array. The array is stacked once
    per count and shared by every reader (so read-only): a point reads its stacks several times, and a
    full frame's copy costs about as much as its merge."""

    def __init__(self) -> None:
        self._frames: list[np.ndarray] = []
        self._array: np.ndarray | None = None

    def append(self, frame: np.ndarray) -> None:
        self._frames.append(frame)
        self._array = None

    def __len__(self) -> int:
        return len(self._frames)

    def array(self) -> np.ndarray:
        if self._array is None:         # one frame, the usual count, is its own stack: a view, not a copy
            self._array = self._frames[0][np.newaxis] if len(self._frames) == 1 else np.stack(self._frames)
            self._array.flags.writeable = False
        return self._array


class _Shots:
    """The raw frames of one point by exposure time, each taken only when first needed."""

    def __init__(self, camera: LuminanceCamera, window: Window):
        self.camera = camera
        self.window = window
        self._frames: dict[float, FrameStack] = {}
        self._realised: dict[float, list[float]] = {}

    def take(self, exposure_s: float, count: int) -> np.ndarray:
        """All frames (≥ count, H, W) at exposure_s, taking only those still missing."""
        frames = self._frames.setdefault(exposure_s, FrameStack())
        realised = self._realised.setdefault(exposure_s, [])
        while len(frames) < count:
            frame = self.camera.capture(exposure_s, self.window)
            frames.append(_pixels(self.camera, frame, self.window))
            realised.append(frame.exposure_s)
        return frames.array()

    def realised_s(self, exposure_s: float) -> float:
        """Mean exposure time the camera realised for the frames at exposure_s."""
        return float(np.mean(self._realised[exposure_s]))

    @property
    def n_taken(self) -> int:
        return sum(len(frames) for frames in self._frames.values())

    @property
    def exposed_s(self) -> float:
        return float(sum(map(sum, self._realised.values())))


def _metered_exposure(shots: _Shots, in_roi: tuple[slice, ...], darks: DarkFrameCache,
                      sensor: SensorInfo, settings: CaptureSettings) -> float:
    """Ladder exposure putting the ROI peak at target_fraction; the probe if that saturates.

    The black level stands in for the dark frame, which only shifts the peak by
    the dark current and saves darks of exposures that are not kept.
    """
    threshold = saturation_threshold_dn(sensor)
    target_dn = settings.target_fraction * (threshold - sensor.black_level_dn)
    t = darks.snap(settings.probe_exposure_s, sensor)
    for _ in range(MAX_METERING_STEPS):
        raw = shots.take(t, 1)[in_roi][0]
        if np.any(raw >= threshold):
            break          # peak unknown: keep t, shorter exposures come after
        peak_dn = float(raw.max()) - sensor.black_level_dn
        t_next = darks.snap(t * target_dn / max(peak_dn, MIN_PEAK_DN), sensor)
        if t_next <= 2 * t:
            if abs(np.log2(t_next / t)) > KEEP_TOLERANCE_STOPS:
                t = t_next
            break
        t = t_next         # under-exposed by over a stop: the peak was mostly noise, meter again
    return t


def _adaptive_exposures(shots: _Shots, metered_s: float, in_roi: tuple[slice, ...], region: tuple[slice, ...],
                        darks: DarkFrameCache, sensor: SensorInfo, settings: CaptureSettings) -> list[float]:
    """The metered exposure and the shorter ones the ROI's saturated pixels need (module docstring).

    `in_roi` and `region` index the ROI and the merged region in a stack of frames.
    """
    threshold = saturation_threshold_dn(sensor)
    exposures = [metered_s]
    while (np.any(shots.take(exposures[-1], 1)[in_roi] >= threshold)
           and len(exposures) < settings.max_exposures and exposures[-1] > sensor.min_exposure_s):
        shorter = max(exposures[-1] * 2.0 ** -settings.bracket_stops, sensor.min_exposure_s)
        exposures.append(darks.snap(shorter, sensor))

    def saturated_everywhere(stack: np.ndarray) -> bool:
        """Every pixel of the merged region saturated in a frame; the ROI, inside it, is looked at first."""
        return all(bool(np.all(np.any(stack[part] >= threshold, axis=0))) for part in (in_roi, region))
    # An exposure saturated everywhere in the merged region adds nothing; keep at least the shortest.
    return [e for e in exposures if not saturated_everywhere(shots.take(e, 1))] or [exposures[-1]]


def fixed_bracket(centre_s: float, settings: CaptureSettings, darks: DarkFrameCache,
                  sensor: SensorInfo) -> list[float]:
    """`bracket_count` ladder exposures `bracket_step_stops` apart around centre_s, shortest first.

    The bracket is shifted, not truncated, where it would leave the sensor's
    range, so that it keeps its count as a vendor's HDR mode does.
    """
    offsets = settings.bracket_step_stops * (np.arange(settings.bracket_count) - (settings.bracket_count - 1) / 2)
    centre = np.clip(np.log2(centre_s), np.log2(sensor.min_exposure_s) - offsets[0],
                     np.log2(sensor.max_exposure_s) - offsets[-1])
    return list(dict.fromkeys(darks.snap(2.0 ** (centre + o), sensor) for o in offsets))


def frames_for_snr(mean: float, var_frames: float, var_dark: float, n: int, m: int,
                   settings: CaptureSettings) -> int:
    """Frames per exposure, ≥ n, for the ROI mean's camera-noise SNR to reach target_snr.

    With n frames and m darks per exposure the mean's variance is var_frames +
    var_dark; var_frames falls as 1/n, var_dark as 1/m, and darks are topped up
    to the frame count. Returns max_frames if no count reaches the target, and n
    if max_frames could not even reach min_snr (averaging would be wasted).
    """
    counts = np.arange(n, settings.max_frames + 1)
    snr = mean / np.sqrt(var_frames * n / counts + var_dark * m / np.maximum(m, counts))
    if snr[-1] < settings.min_snr:
        return n
    reached = snr >= settings.target_snr
    return int(counts[np.argmax(reached)]) if reached.any() else settings.max_frames


@dataclass(frozen=True)
class Acquisition:
    """Everything one point took from the camera; `reduce_point` turns it into numbers.

    Split from the reduction so that the run engine can start the next move in
    between: a full-frame merge (images saved) takes about a second.
    """

    sensor: SensorInfo
    settings: CaptureSettings
    roi: Window
    window: Window                      # what the camera read
    frames: tuple[np.ndarray, ...]      # per exposure: (n, H, W) raw frames of `window`
    darks: tuple[np.ndarray, ...]       # per exposure: (m, H, W) dark frames of `window`
    exposures_s: tuple[float, ...]      # realised
    roi_merge: HdrMerge                 # the ROI's merge, from the frame-count decision
    n_frames: int
    n_darks: int
    capture_time_s: float


def acquire_point(camera: LuminanceCamera, settings: CaptureSettings,
                  darks: DarkFrameCache) -> Acquisition | CalibratedAcquisition:
    """Expose the current view as the ROI needs (see the module docstring); decisions look at the ROI only.

    A camera delivering calibrated luminance takes its own picture, and no darks (calibrated_capture).
    """
    if isinstance(camera, CalibratedLuminanceCamera):
        return acquire_calibrated(camera, settings, darks.clock)
    sensor = camera.sensor
    roi, window = point_windows(camera, settings)
    start_s = darks.clock.now() if darks.clock else 0.0
    darks_before, dark_exposed_before = darks.n_taken, darks.exposed_s
    region = window if settings.full_frame else roi
    in_window, in_region = ((slice(None), *window.inner(w)) for w in (roi, region))   # in a frame stack
    shots = _Shots(camera, window)
    # Images saved: the metering probes read only the window around the ROI, since nothing outside the ROI
    # decides the exposure; the exposures kept are read whole (a probe kept is read again).
    meter = _Shots(camera, point_windows(camera, replace(settings, full_frame=False))[1]) \
        if settings.full_frame else shots

    metered_s = _metered_exposure(meter, (slice(None), *meter.window.inner(roi)), darks, sensor, settings)
    if settings.mode == "fixed_bracket":
        exposures = fixed_bracket(metered_s, settings, darks, sensor)
    else:
        exposures = _adaptive_exposures(shots, metered_s, in_window, in_region, darks, sensor, settings)

    def roi_merge(n: int) -> tuple[HdrMerge, int]:
        """Merge of n frames per exposure over the ROI, and the fewest darks per exposure."""
        dark = [darks.get(camera, e, window, n, settings.dark_max_age_s)[in_window] for e in exposures]
        return merge_exposures([shots.take(e, n)[in_window] for e in exposures], dark,
                               [shots.realised_s(e) for e in exposures], sensor), min(map(len, dark))

    n_next = settings.frames_per_exposure
    while True:
        n = n_next
        merged, m = roi_merge(n)
        if settings.mode == "adaptive":
            var_noise, var_dark = (mean_noise(v) ** 2 for v in (merged.var_rate, merged.var_dark))
            n_next = frames_for_snr(float(merged.rate_dn_s.mean()), var_noise - var_dark, var_dark,
                                    n, m, settings)
        if n_next == n:
            break
    return Acquisition(
        sensor=sensor, settings=settings, roi=roi, window=window,
        frames=tuple(shots.take(e, n) for e in exposures),
        darks=tuple(darks.get(camera, e, window, n, settings.dark_max_age_s) for e in exposures),
        exposures_s=tuple(shots.realised_s(e) for e in exposures), roi_merge=merged,
        n_frames=shots.n_taken + (meter.n_taken if meter is not shots else 0), n_darks=darks.n_taken - darks_before,
        capture_time_s=(darks.clock.now() - start_s if darks.clock
                        else shots.exposed_s + (meter.exposed_s if meter is not shots else 0.0)
                        + darks.exposed_s - dark_exposed_before))


def reduce_point(acq: Acquisition | CalibratedAcquisition) -> PointCapture:
    """ROI statistics and flags from the ROI's merge, and the whole window merged when images are saved
    (`merged_image`); no camera I/O. The ROI's numbers do not depend on whether images are saved.

    The luminance is the value at the ROI centre: the ROI mean corrected for a resolved lobe's curvature
    (rig.physics.footprint), whose uncertainty adds to u_luminance.

    A camera with a calibration file (`rig calibrate camera`) has its flat field (lens fall-off and PRNU)
    divided out of the merged rate, pixel by pixel, before its coefficient applies."""
    if isinstance(acq, CalibratedAcquisition):
        return reduce_calibrated(acq)
    sensor, settings, merged = acq.sensor, acq.settings, acq.roi_merge
    var_dark = mean_noise(merged.var_dark) ** 2
    cal = calibration_of(sensor, acq.roi)                            # cd/m² per DN/s, per pixel of the ROI
    stats = roi_statistics(merged.rate_dn_s * cal, merged.var_rate * cal ** 2)
    return PointCapture(
        luminance_cd_m2=stats.mean,
        u_luminance_cd_m2=stats.u_luminance(sensor.calibration_u_rel),
        roi_std_cd_m2=stats.std,
        exposures_s=acq.exposures_s,
        saturated_fraction=float(np.mean(merged.saturated)),
        flags=point_flags(stats, settings.min_snr, bool(np.any(merged.clipped))),
        image_cd_m2=merged_image(acq) if settings.full_frame else None,
        roi_window=acq.roi,
        n_frames=acq.n_frames,
        u_noise_cd_m2=stats.u_mean_noise,
        u_dark_cd_m2=float(np.sqrt(var_dark) * cal.mean()),
        u_texture_cd_m2=stats.u_texture,
        u_lobe_cd_m2=stats.u_lobe,
        lobe_bias_rel=stats.lobe_bias_rel,
        lobe_width_rel=stats.lobe_width_rel,
        lobe_slope_rel=stats.lobe_slope_rel,
        capture_time_s=acq.capture_time_s,
        n_darks=acq.n_darks,
    )


def merged_image(acq: Acquisition) -> np.ndarray:
    """The whole window merged, in cd/m² (float32): the image saved with a point."""
    image = merged_rate(acq.frames, acq.darks, acq.exposures_s, acq.sensor)
    # in float32: `image *=` a float64 calibration would go through a float64 copy of the frame
    return np.multiply(image, calibration_of(acq.sensor, acq.window), out=image, dtype=np.float32)


def calibration_of(sensor: SensorInfo, window: Window) -> np.ndarray:
    """cd/m² per DN/s of the pixels of `window` (float64): the camera's coefficient over its flat field (lens
    fall-off and PRNU), (height, width), where `rig calibrate camera` measured one; else the coefficient
    alone, as a 0-d array (it broadcasts)."""
    if isinstance(sensor, CalibratedSensorInfo):
        return sensor.calibration_cd_m2_per_dn_s / sensor.flat_of(window)
    return np.asarray(sensor.calibration_cd_m2_per_dn_s, dtype=float)


def capture_point(camera: LuminanceCamera, settings: CaptureSettings, darks: DarkFrameCache) -> PointCapture:
    """Expose, merge and reduce the ROI of the current view (see the module docstring)."""
    return reduce_point(acquire_point(camera, settings, darks))
