"""HDR capture of one measurement point with a camera that delivers raw frames: the raw path.

`RawCapturer` (chosen by rig.acquisition.capturer for a `LuminanceCamera` that is not a
`CalibratedLuminanceCamera`) drives the camera: it chooses the exposures the ROI needs
(Hasinoff et al. 2010: scene-adapted exposure sets beat fixed brackets), takes
them with the run's cached dark frames (rig.acquisition.frames), and its `Acquisition` hands
the raw data to the pure physics in `rig.physics.hdr` (merge) and `rig.physics.roi` (ROI
statistics) when it is reduced. The windows read and the metering constants are
rig.acquisition.metering's.

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

from dataclasses import dataclass

import numpy as np

from rig.acquisition.frames import DarkFrameCache, FrameStack, pixels_of
from rig.acquisition.metering import KEEP_STOPS, METERING_STEPS, MIN_PEAK_DN, metering_window, point_windows
from rig.acquisition.tending import TendedCamera
from rig.config.capture import CaptureSettings
from rig.core.clock import Clock
from rig.core.values import PointCapture, SensorInfo, Window
from rig.drivers.interfaces import LuminanceCamera
from rig.physics.camera_calibration import calibration_of
from rig.physics.hdr import HdrMerge, merge_exposures, merged_rate, saturation_threshold_dn
from rig.physics.roi import mean_noise, point_flags, roi_statistics


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
            frames.append(pixels_of(self.camera, frame, self.window))
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
    for _ in range(METERING_STEPS):
        raw = shots.take(t, 1)[in_roi][0]
        if np.any(raw >= threshold):
            break          # peak unknown: keep t, shorter exposures come after
        peak_dn = float(raw.max()) - sensor.black_level_dn
        t_next = darks.snap(t * target_dn / max(peak_dn, MIN_PEAK_DN), sensor)
        if t_next <= 2 * t:
            if abs(np.log2(t_next / t)) > KEEP_STOPS:
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
    """Everything one point took from the camera; `reduce()` turns it into numbers.

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

    @property
    def clipped(self) -> bool:
        """Whether ROI pixels saturated in every exposure (their rate is only a lower bound): a denser
        filter would help (rig.acquisition.attenuation)."""
        return bool(np.any(self.roi_merge.clipped))

    def reduce(self) -> PointCapture:
        """ROI statistics and flags from the ROI's merge, and the whole window merged when images are saved
        (`merged_image`); no camera I/O. The ROI's numbers do not depend on whether images are saved.

        The luminance is the value at the ROI centre: the ROI mean corrected for a lobe's curvature where it is
        resolved or the slope is clear (rig.physics.roi), whose uncertainty adds to u_luminance.

        A camera with a calibration file (`rig calibrate camera`) has its flat field (lens fall-off and PRNU)
        divided out of the merged rate, pixel by pixel, before its coefficient applies."""
        sensor, settings, merged = self.sensor, self.settings, self.roi_merge
        var_dark = mean_noise(merged.var_dark) ** 2
        cal = calibration_of(sensor, self.roi)                           # cd/m² per DN/s, per pixel of the ROI
        stats = roi_statistics(merged.rate_dn_s * cal, merged.var_rate * cal ** 2)
        return PointCapture(
            **stats.capture_fields(),
            u_luminance_cd_m2=stats.u_luminance(sensor.calibration_u_rel),
            exposures_s=self.exposures_s,
            saturated_fraction=float(np.mean(merged.saturated)),
            flags=point_flags(stats, settings.min_snr, bool(np.any(merged.clipped))),
            image_cd_m2=self.merged_image() if settings.full_frame else None,
            roi_window=self.roi,
            n_frames=self.n_frames,
            u_noise_cd_m2=stats.u_mean_noise,
            u_dark_cd_m2=float(np.sqrt(var_dark) * cal.mean()),
            capture_time_s=self.capture_time_s,
            n_darks=self.n_darks,
        )

    def merged_image(self) -> np.ndarray:
        """The whole window merged, in cd/m² (float32): the image saved with a point."""
        image = merged_rate(self.frames, self.darks, self.exposures_s, self.sensor)
        # in float32: `image *=` a float64 calibration would go through a float64 copy of the frame
        return np.multiply(image, calibration_of(self.sensor, self.window), out=image, dtype=np.float32)


class RawCapturer:
    """Captures the points of a run with a camera that delivers raw frames (module docstring).

    It owns the run's dark frames and receives the run's `clock`: each point is timed on it, darks age on
    it, and due keep-alives run on it after every frame (rig.acquisition.tending). Without a clock (a
    bench, a test) a point's time is its summed exposures, and darks cannot age (dark_max_age_s must be None).
    """

    def __init__(self, camera: LuminanceCamera, settings: CaptureSettings, clock: Clock | None = None):
        self.camera: LuminanceCamera = TendedCamera(camera, clock) if clock else camera
        self.settings, self.clock = settings, clock
        self.darks = DarkFrameCache(frames_per_dark=settings.frames_per_exposure, clock=clock)
        self.roi, self.window = point_windows(camera, settings)
        # Images saved: the metering probes read only the window around the ROI, since nothing outside the ROI
        # decides the exposure; the exposures kept are read whole (a probe kept is read again).
        self.metering_window = metering_window(camera, settings)

    @property
    def sensor(self) -> SensorInfo:
        return self.camera.sensor

    def acquire(self) -> Acquisition:
        """Expose the current view as the ROI needs (module docstring); decisions look at the ROI only."""
        camera, settings, darks, clock, window = self.camera, self.settings, self.darks, self.clock, self.window
        start_s = clock.now() if clock else 0.0
        darks_before, dark_exposed_before = darks.n_taken, darks.exposed_s
        shots = _Shots(camera, window)
        meter = _Shots(camera, self.metering_window) if settings.full_frame else shots
        exposures = self._exposures(shots, meter)
        merged, n = self._averaged(shots, exposures)
        taken = (shots,) if meter is shots else (shots, meter)
        return Acquisition(
            sensor=camera.sensor, settings=settings, roi=self.roi, window=window,
            frames=tuple(shots.take(e, n) for e in exposures),
            darks=tuple(darks.get(camera, e, window, n, settings.dark_max_age_s) for e in exposures),
            exposures_s=tuple(shots.realised_s(e) for e in exposures), roi_merge=merged,
            n_frames=sum(s.n_taken for s in taken), n_darks=darks.n_taken - darks_before,
            capture_time_s=(clock.now() - start_s if clock
                            else sum(s.exposed_s for s in taken) + darks.exposed_s - dark_exposed_before))

    def _exposures(self, shots: _Shots, meter: _Shots) -> list[float]:
        """The ladder exposures the point is merged from: metered on `meter`'s window, taken on `shots`'."""
        settings, darks, sensor = self.settings, self.darks, self.camera.sensor
        metered_s = _metered_exposure(meter, (slice(None), *meter.window.inner(self.roi)), darks, sensor, settings)
        if settings.mode == "fixed_bracket":
            return fixed_bracket(metered_s, settings, darks, sensor)
        region = self.window if settings.full_frame else self.roi
        in_window, in_region = ((slice(None), *self.window.inner(w)) for w in (self.roi, region))  # in a stack
        return _adaptive_exposures(shots, metered_s, in_window, in_region, darks, sensor, settings)

    def _averaged(self, shots: _Shots, exposures: list[float]) -> tuple[HdrMerge, int]:
        """The ROI's merge of n frames per exposure, n from frames_per_exposure up until the camera-noise SNR
        is reached (adaptive; module docstring), and n."""
        camera, settings, darks, window, sensor = self.camera, self.settings, self.darks, self.window, self.sensor
        in_window = (slice(None), *window.inner(self.roi))

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
                return merged, n

    def probe(self, exposure_s: float) -> tuple[float, float]:
        """One frame of the ROI alone at exposure_s: its brightest pixel above black level as a fraction of the
        usable range, and the exposure the camera realised (the attenuator's look at a clearer filter)."""
        sensor = self.camera.sensor
        frame = self.camera.capture(exposure_s, self.roi)
        usable = saturation_threshold_dn(sensor) - sensor.black_level_dn
        return (float(np.max(frame.pixels_dn)) - sensor.black_level_dn) / usable, frame.exposure_s
