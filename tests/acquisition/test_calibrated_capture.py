"""Capture of a point with a camera that delivers calibrated luminance (rig.acquisition.calibrated_capture),
the capturer rig.acquisition.capturer chooses for it.

A fake calibrated camera returns windows of a known luminance scene; the PointCapture is checked
against closed forms (mean, pixel spread, calibration term, saturated fractions, metered exposure).
"""

import math

import numpy as np
import pytest

from rig.acquisition.calibrated_capture import CalibratedCapturer
from rig.acquisition.capturer import capturer_for
from rig.config.capture import CaptureSettings
from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.core.values import LuminanceImage, SensorInfo, Window
from rig.drivers.interfaces import CalibratedLuminanceCamera
from rig.physics.roi import block_means, u_mean_of_blocks

WIDTH, HEIGHT = 120, 80
#: Luminance × exposure (cd·s/m²) that fills the fake sensor's range.
FULL_RANGE_CD_S_M2 = 10.0
SINGLE = CaptureSettings(roi_px=40, max_exposures=1)     # one exposure: a metered single picture
HDR = CaptureSettings(roi_px=40)                         # adaptive, up to 5 exposures: one HDR picture


class StepClock(Clock):
    def __init__(self):
        self.t = 50.0

    def now(self):
        return self.t

    def sleep(self, seconds):
        self.t += seconds


class FakeCalibratedCamera(CalibratedLuminanceCamera):
    """A fixed luminance scene (cd/m²); overflow where scene × exposure exceeds FULL_RANGE_CD_S_M2."""

    def __init__(self, scene: np.ndarray, calibration_u_rel: float = 0.0, locates_overflow: bool = True,
                 clock: StepClock | None = None):
        self.scene = scene.astype(np.float32)
        self.locates_overflow = locates_overflow
        self.clock = clock
        self.calls: list[tuple] = []
        self.sensor = SensorInfo(width_px=WIDTH, height_px=HEIGHT, bit_depth=12, gain_dn_per_e=1.0, read_noise_e=0.0,
                                 black_level_dn=0.0, calibration_cd_m2_per_dn_s=1.0,
                                 calibration_u_rel=calibration_u_rel, min_exposure_s=1e-4, max_exposure_s=4.0)

    def identity(self):
        return "fake calibrated camera"

    def _image(self, exposures_s, algorithm, window):
        window = window or self.full_window()
        if self.clock:
            self.clock.sleep(sum(exposures_s) + 0.5)      # exposures plus LabSoft's own work
        over = self.scene * min(exposures_s) > FULL_RANGE_CD_S_M2
        rows, cols = Window(0, 0, WIDTH, HEIGHT).inner(window)
        return LuminanceImage(pixels_cd_m2=self.scene[rows, cols].copy(), window=window,
                              exposures_s=tuple(exposures_s), algorithm=algorithm,
                              overflow_fraction=float(over.mean()),
                              peak_load=float(self.scene.max() * max(exposures_s) / FULL_RANGE_CD_S_M2),
                              saturated=over[rows, cols] if self.locates_overflow else None)

    def capture_luminance(self, exposure_s, window=None):
        self.calls.append(("single", exposure_s, window))
        return self._image((exposure_s,), "single", window)

    def capture_hdr_luminance(self, max_exposure_s, min_exposure_s, factor, window=None):
        """Exposures `factor` apart from the longest down to the first that does not overflow (or the shortest)."""
        self.calls.append(("hdr", max_exposure_s, min_exposure_s, factor, window))
        exposures = [max_exposure_s]
        while self.scene.max() * exposures[-1] > FULL_RANGE_CD_S_M2 and exposures[-1] / factor >= min_exposure_s:
            exposures.append(exposures[-1] / factor)
        return self._image(exposures, "high_dynamic", window)


def roi_of(image: np.ndarray, roi_px: int = 40) -> np.ndarray:
    r0, c0 = (HEIGHT - roi_px) // 2, (WIDTH - roi_px) // 2
    return image[r0:r0 + roi_px, c0:c0 + roi_px]


def capture(camera, settings, clock=None):
    return capturer_for(camera, settings, clock).acquire().reduce()


def test_uniform_scene_gives_its_luminance_and_only_the_calibration_uncertainty():
    camera = FakeCalibratedCamera(np.full((HEIGHT, WIDTH), 250.0), calibration_u_rel=0.02)
    cap = capture(camera, HDR)
    assert cap.luminance_cd_m2 == pytest.approx(250.0, rel=1e-6)
    assert cap.u_luminance_cd_m2 == pytest.approx(0.02 * 250.0, rel=1e-6)
    assert cap.roi_std_cd_m2 == pytest.approx(0.0, abs=1e-9)
    assert cap.flags == ()
    assert cap.roi_window == Window(40, 20, 40, 40)
    assert (cap.n_darks, cap.u_noise_cd_m2, cap.u_dark_cd_m2) == (0, 0.0, 0.0)
    assert cap.image_cd_m2 is None


def test_gradient_scene_mean_spread_and_uncertainty_are_the_closed_forms():
    a, b = 100.0, 2.0                                 # L = a + b·column
    scene = a + b * np.arange(WIDTH)[None, :] * np.ones((HEIGHT, 1))
    cap = capture(FakeCalibratedCamera(scene, calibration_u_rel=0.01), HDR)
    columns = np.arange(40, 80)                       # the ROI's columns
    mean = a + b * columns.mean()
    # A clear slope: the ROI is corrected to its centre value by the lobe fit (rig.physics.roi), whose log-quadratic
    # model misses a linear gradient's log by 1e-5 of the value; the texture it leaves is as small
    assert cap.luminance_cd_m2 == pytest.approx(mean, rel=2e-5)
    # Every ROI row holds the same 40 columns: the pixel spread is b × the columns' spread.
    n = 40 * 40
    assert cap.roi_std_cd_m2 == pytest.approx(b * columns.std() * math.sqrt(n / (n - 1)), rel=1e-5)
    assert u_mean_of_blocks(block_means(roi_of(scene))) < 1e-9 * mean            # the blocks lie on a plane
    assert math.hypot(cap.u_texture_cd_m2, cap.u_lobe_cd_m2) < 2e-4 * mean        # no noise known: no texture
    assert cap.u_luminance_cd_m2 == pytest.approx(0.01 * mean, rel=1e-3)          # the calibration's u


def test_overflow_the_camera_locates_in_the_roi_flags_it_with_the_roi_fraction():
    scene = np.full((HEIGHT, WIDTH), 10.0)
    scene[20:30, 40:60] = 1e6                         # 10 × 20 px of the 40 × 40 ROI overflow at every exposure
    cap = capture(FakeCalibratedCamera(scene), HDR)
    assert "roi_saturated" in cap.flags
    assert cap.saturated_fraction == pytest.approx(200 / 1600)


def test_overflow_outside_the_roi_does_not_flag_it_when_the_camera_locates_it():
    scene = np.full((HEIGHT, WIDTH), 10.0)
    scene[0:5, 0:5] = 1e6
    cap = capture(FakeCalibratedCamera(scene), HDR)
    assert "roi_saturated" not in cap.flags
    assert cap.saturated_fraction == 0.0


def test_overflow_the_camera_cannot_locate_flags_the_point_with_the_picture_fraction():
    scene = np.full((HEIGHT, WIDTH), 10.0)
    scene[0:5, 0:5] = 1e6                             # outside the ROI, but the camera only reports a fraction
    cap = capture(FakeCalibratedCamera(scene, locates_overflow=False), HDR)
    assert "roi_saturated" in cap.flags
    assert cap.saturated_fraction == pytest.approx(25 / (WIDTH * HEIGHT))


def test_a_dark_noisy_roi_is_low_signal():
    scene = np.random.default_rng(3).normal(0.0, 1.0, (HEIGHT, WIDTH))
    cap = capture(FakeCalibratedCamera(scene), HDR)
    assert "low_signal" in cap.flags


def test_hdr_picture_parameters_follow_the_capture_settings():
    camera = FakeCalibratedCamera(np.full((HEIGHT, WIDTH), 5.0))
    cap = capture(camera, CaptureSettings(roi_px=40, bracket_stops=1.5, window_margin_px=3))
    (call,) = camera.calls
    assert call[:4] == ("hdr", 4.0, 1e-4, pytest.approx(2 ** 1.5))
    assert call[4] == Window(37, 17, 46, 46)          # the ROI grown by the margin
    assert cap.exposures_s == pytest.approx((4.0, 4.0 / 2 ** 1.5))    # 5 cd/m² × 1.41 s fits the range
    assert cap.n_frames == 2
    assert cap.capture_time_s == pytest.approx(sum(cap.exposures_s))   # no clock: the summed exposures
    fixed = FakeCalibratedCamera(np.full((HEIGHT, WIDTH), 5.0))
    capture(fixed, CaptureSettings(roi_px=40, mode="fixed_bracket", bracket_step_stops=2.0))
    assert fixed.calls[0][3] == pytest.approx(4.0)


def test_single_picture_is_metered_to_the_target_load():
    scene = np.full((HEIGHT, WIDTH), 100.0)           # peak load = 100 × t / 10
    camera = FakeCalibratedCamera(scene)
    cap = capture(camera, SINGLE)
    times = [c[1] for c in camera.calls]
    assert times == pytest.approx([0.002, 0.7 * FULL_RANGE_CD_S_M2 / 100.0])
    assert cap.exposures_s == pytest.approx((0.07,))
    assert cap.n_frames == 2
    assert cap.luminance_cd_m2 == pytest.approx(100.0, rel=1e-6)


def test_single_picture_shortens_while_the_camera_reports_overflow():
    camera = FakeCalibratedCamera(np.full((HEIGHT, WIDTH), 2e4))   # overflows above 0.5 ms
    cap = capture(camera, CaptureSettings(roi_px=40, max_exposures=1, probe_exposure_s=0.004, bracket_stops=2.0))
    # 4 ms and 1 ms overflow; 0.25 ms loads 0.5, within half a stop of the 0.35 ms that would load 0.7: kept.
    assert [c[1] for c in camera.calls] == pytest.approx([0.004, 0.001, 0.00025])
    assert cap.flags == () and cap.n_frames == 3


def test_full_frame_returns_the_whole_picture():
    scene = np.arange(WIDTH * HEIGHT, dtype=float).reshape(HEIGHT, WIDTH)
    camera = FakeCalibratedCamera(scene)
    cap = capture(camera, CaptureSettings(roi_px=40, full_frame=True))
    assert camera.calls[0][4] == Window(0, 0, WIDTH, HEIGHT)
    np.testing.assert_allclose(cap.image_cd_m2, scene)
    # The ramp's clear slope is corrected by the lobe fit, whose log-quadratic misses this ±50 % linear ramp by 6e-4,
    # a fifth of the u it states
    assert cap.luminance_cd_m2 == pytest.approx(roi_of(scene).mean(), rel=1e-3)
    assert abs(cap.luminance_cd_m2 - roi_of(scene).mean()) < cap.u_luminance_cd_m2


def test_capture_time_is_rig_time_on_the_clock_and_no_darks_are_taken():
    clock = StepClock()
    camera = FakeCalibratedCamera(np.full((HEIGHT, WIDTH), 5.0), clock=clock)
    capturer = capturer_for(camera, HDR, clock)
    acquisition = capturer.acquire()
    cap = acquisition.reduce()
    assert cap.capture_time_s == pytest.approx(sum(cap.exposures_s) + 0.5)
    assert isinstance(capturer, CalibratedCapturer) and not hasattr(capturer, "darks") and cap.n_darks == 0
    assert not acquisition.clipped          # the camera has its own attenuation: a filter wheel stays clear


def test_raw_frames_are_refused_with_a_clear_message():
    camera = FakeCalibratedCamera(np.full((HEIGHT, WIDTH), 5.0))
    with pytest.raises(DeviceError, match="fake calibrated camera: delivers calibrated luminance only"):
        camera.capture(0.01)
    with pytest.raises(DeviceError, match="its own dark frames"):
        camera.capture_dark(0.01)


class BadCamera(FakeCalibratedCamera):
    def __init__(self, fault):
        super().__init__(np.full((HEIGHT, WIDTH), 5.0))
        self.fault = fault

    def capture_hdr_luminance(self, max_exposure_s, min_exposure_s, factor, window=None):
        image = super().capture_hdr_luminance(max_exposure_s, min_exposure_s, factor, window)
        pixels = image.pixels_cd_m2
        if self.fault == "shape":
            pixels = pixels[:-1]
        elif self.fault == "nan":
            pixels = pixels.copy()
            pixels[30, 30] = np.nan
        return LuminanceImage(pixels, image.window, image.exposures_s, image.algorithm, image.overflow_fraction)


@pytest.mark.parametrize(("fault", "message"), [("shape", r"returned a \(39, 40\) picture"),
                                                ("nan", "returned 1 non-finite luminance values in the ROI")])
def test_a_malformed_picture_is_a_device_error_naming_the_camera(fault, message):
    with pytest.raises(DeviceError, match=f"fake calibrated camera: {message}"):
        capture(BadCamera(fault), HDR)


def test_the_probe_is_one_picture_of_the_roi_and_its_peak_load():
    camera = FakeCalibratedCamera(np.full((HEIGHT, WIDTH), 5.0))
    capturer = capturer_for(camera, HDR)
    assert capturer.probe(0.5) == (pytest.approx(5.0 * 0.5 / FULL_RANGE_CD_S_M2), 0.5)
    assert camera.calls == [("single", 0.5, Window(40, 20, 40, 40))]


def test_the_capturer_lets_the_keep_alives_run_after_each_picture():
    """On the run's clock the capturer drives the camera through rig.acquisition.tending's wrapper."""
    clock = StepClock()
    slept = []
    clock.sleep = lambda s: slept.append(s)
    camera = FakeCalibratedCamera(np.full((HEIGHT, WIDTH), 5.0))
    capturer_for(camera, SINGLE, clock).acquire()
    assert len(camera.calls) >= 2 and slept == [0.0] * len(camera.calls)
