import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings as hyp_settings, strategies as st

from drivers.interfaces import DeviceError, Frame, LuminanceCamera, SensorInfo, Window
from rig.capture import CaptureSettings, DarkFrameCache, capture_point
from rig.hdr import saturation_threshold_dn

GAIN_DN_PER_E = 0.25
CAL_CD_M2_PER_DN_S = 0.01
SETTINGS = CaptureSettings(roi_px=40)


class FakeCamera(LuminanceCamera):
    """Scene of fixed photo-electron rates (e⁻/s per pixel) seen by an EMVA 1288 sensor."""

    def __init__(self, scene_e_s: np.ndarray, seed: int = 0, dark_e_s: float = 50.0,
                 calibration_u_rel: float = 0.0):
        self.scene_e_s = scene_e_s
        self.dark_e_s = dark_e_s
        self.rng = np.random.default_rng(seed)
        self.sensor = SensorInfo(width_px=scene_e_s.shape[1], height_px=scene_e_s.shape[0], bit_depth=12,
                                 gain_dn_per_e=GAIN_DN_PER_E, read_noise_e=8.0, black_level_dn=64.0,
                                 calibration_cd_m2_per_dn_s=CAL_CD_M2_PER_DN_S,
                                 calibration_u_rel=calibration_u_rel, min_exposure_s=1e-4, max_exposure_s=10.0)
        self.light_calls: list[tuple[float, Window]] = []
        self.dark_calls: list[tuple[float, Window]] = []

    def identity(self) -> str:
        return "fake camera"

    def _expose(self, rate_e_s: np.ndarray, exposure_s: float, window: Window, dark: bool) -> Frame:
        rows, cols = self.full_window().inner(window)
        electrons = self.rng.poisson((rate_e_s[rows, cols] + self.dark_e_s) * exposure_s)
        dn = np.round(GAIN_DN_PER_E * (electrons + self.rng.normal(0, 8.0, electrons.shape)) + 64.0)
        return Frame(np.clip(dn, 0, 4095).astype(np.uint16), exposure_s, window, dark=dark)

    def capture(self, exposure_s, window=None):
        window = window or self.full_window()
        self.light_calls.append((exposure_s, window))
        return self._expose(self.scene_e_s, exposure_s, window, dark=False)

    def capture_dark(self, exposure_s, window=None):
        window = window or self.full_window()
        self.dark_calls.append((exposure_s, window))
        return self._expose(np.zeros_like(self.scene_e_s), exposure_s, window, dark=True)


def flat(rate_e_s: float, shape=(100, 120)) -> np.ndarray:
    return np.full(shape, rate_e_s)


def luminance(rate_e_s):
    return np.mean(rate_e_s) * GAIN_DN_PER_E * CAL_CD_M2_PER_DN_S


def roi_of(camera, capture):
    rows, cols = camera.full_window().inner(capture.roi_window)
    return camera.scene_e_s[rows, cols]


def test_exposure_puts_the_peak_near_the_target_without_saturating():
    camera = FakeCamera(flat(1.0e5))
    capture = capture_point(camera, SETTINGS, DarkFrameCache())
    assert len(capture.exposures_s) == 1 and capture.saturated_fraction == 0.0 and capture.flags == ()
    ideal_s = 0.7 * (saturation_threshold_dn(camera.sensor) - 64) / (1.0e5 * GAIN_DN_PER_E)
    assert 0.6 * ideal_s < capture.exposures_s[0] <= 1.1 * ideal_s
    assert capture.luminance_cd_m2 == pytest.approx(luminance(1.0e5), abs=4 * capture.u_luminance_cd_m2)
    assert capture.roi_window == Window(40, 30, 40, 40) and capture.image_cd_m2 is None
    assert all(window == capture.roi_window for _, window in camera.light_calls + camera.dark_calls)
    assert capture.n_frames == len(camera.light_calls)


def test_a_bright_roi_is_exposed_short_enough():
    camera = FakeCamera(flat(1.0e8))                  # the 2 ms probe collects 10× the full well
    capture = capture_point(camera, SETTINGS, DarkFrameCache())
    assert capture.exposures_s == (2.0 ** -13,)        # probe 2⁻⁹ s → 2⁻¹¹ s → 2⁻¹³ s
    assert capture.saturated_fraction == 0.0 and capture.flags == ()
    assert capture.luminance_cd_m2 == pytest.approx(luminance(1.0e8), abs=4 * capture.u_luminance_cd_m2)


def test_a_high_dynamic_range_roi_gets_several_exposures_and_an_unbiased_mean():
    checker = np.indices((100, 120)).sum(axis=0) % 2 == 0
    camera = FakeCamera(np.where(checker, 5.0e7, 5.0e5))     # 100:1 within every 10-px block
    capture = capture_point(camera, SETTINGS, DarkFrameCache())
    assert len(capture.exposures_s) >= 2 and capture.flags == ()
    assert capture.saturated_fraction == pytest.approx(0.5)
    truth = luminance(roi_of(camera, capture))
    assert capture.luminance_cd_m2 == pytest.approx(truth, abs=4 * capture.u_luminance_cd_m2)
    assert capture.u_luminance_cd_m2 < 0.002 * truth


def test_a_dim_roi_gets_the_longest_exposure_and_is_flagged():
    camera = FakeCamera(flat(0.0))
    capture = capture_point(camera, SETTINGS, DarkFrameCache())
    assert capture.exposures_s == (10.0,) and "low_signal" in capture.flags
    assert capture.luminance_cd_m2 == pytest.approx(0.0, abs=4 * capture.u_luminance_cd_m2)


def test_a_roi_saturated_at_the_shortest_exposure_is_flagged():
    camera = FakeCamera(flat(1.0e10))
    capture = capture_point(camera, SETTINGS, DarkFrameCache())
    assert capture.exposures_s == (1e-4,) and "roi_saturated" in capture.flags
    assert capture.saturated_fraction == 1.0
    assert np.isfinite(capture.luminance_cd_m2) and capture.luminance_cd_m2 < luminance(1.0e10)


def test_max_exposures_bounds_the_bracket():
    camera = FakeCamera(flat(1.0e10))
    capture_point(camera, dataclasses.replace(SETTINGS, max_exposures=2), DarkFrameCache())
    assert len({t for t, _ in camera.light_calls}) == 2


def test_darks_are_reused_across_points():
    camera, darks = FakeCamera(flat(1.0e8)), DarkFrameCache()
    capture_point(camera, SETTINGS, darks)
    taken = darks.n_taken
    capture_point(camera, SETTINGS, darks)
    assert darks.n_taken == taken == len(camera.dark_calls) == 1


def test_dark_cache_keys_on_time_and_window_and_can_be_invalidated():
    camera, darks = FakeCamera(flat(0.0)), DarkFrameCache(frames_per_dark=2)
    t = darks.snap(0.01, camera.sensor)
    roi, full = Window(10, 10, 20, 20), camera.full_window()
    assert darks.get(camera, t, roi).shape == (2, 20, 20)
    darks.get(camera, t, roi)
    darks.get(camera, t, full)
    darks.get(camera, darks.snap(0.02, camera.sensor), roi)
    assert len(camera.dark_calls) == 6 and len(darks) == 3
    darks.invalidate()
    darks.get(camera, t, roi)
    assert len(camera.dark_calls) == 8
    with pytest.raises(ValueError):
        darks.get(camera, 0.0123, roi)


@hyp_settings(max_examples=100, deadline=None)
@given(exposure_s=st.floats(1e-6, 100.0))
def test_snap_is_idempotent_and_stays_in_range(exposure_s):
    sensor = FakeCamera(flat(0.0, (2, 2))).sensor
    snapped = DarkFrameCache().snap(exposure_s, sensor)
    assert sensor.min_exposure_s <= snapped <= sensor.max_exposure_s
    assert DarkFrameCache().snap(snapped, sensor) == snapped
    if sensor.min_exposure_s * 1.06 < exposure_s < sensor.max_exposure_s / 1.06:
        assert abs(np.log2(snapped / exposure_s)) <= 1 / 12 + 1e-12


def test_frame_averaging_and_full_frame():
    camera = FakeCamera(flat(1.0e5))
    settings = dataclasses.replace(SETTINGS, frames_per_exposure=3, full_frame=True)
    capture = capture_point(camera, settings, DarkFrameCache())
    merged_s = capture.exposures_s[0]
    assert sum(t == merged_s for t, _ in camera.light_calls) == 3
    assert capture.image_cd_m2.shape == (100, 120)
    assert all(window == camera.full_window() for _, window in camera.light_calls)
    rows, cols = camera.full_window().inner(capture.roi_window)
    assert capture.luminance_cd_m2 == pytest.approx(capture.image_cd_m2[rows, cols].mean())


def test_window_margin_grows_the_read_window_only():
    camera = FakeCamera(flat(1.0e5))
    capture = capture_point(camera, dataclasses.replace(SETTINGS, window_margin_px=5), DarkFrameCache())
    assert capture.roi_window == Window(40, 30, 40, 40)
    assert {window for _, window in camera.light_calls} == {Window(35, 25, 50, 50)}


def test_calibration_uncertainty_is_combined():
    camera = FakeCamera(flat(1.0e5), calibration_u_rel=0.02)
    capture = capture_point(camera, SETTINGS, DarkFrameCache())
    assert 0.02 < capture.u_luminance_cd_m2 / capture.luminance_cd_m2 < 0.021


def test_bad_settings_and_bad_frames_are_refused():
    with pytest.raises(ValueError, match="target_fraction"):
        CaptureSettings(target_fraction=1.5)
    with pytest.raises(ValueError, match="roi_px"):
        capture_point(FakeCamera(flat(1.0, (30, 30))), SETTINGS, DarkFrameCache())

    class CroppingCamera(FakeCamera):
        def capture(self, exposure_s, window=None):
            frame = super().capture(exposure_s, window)
            return dataclasses.replace(frame, pixels_dn=frame.pixels_dn[1:])

    with pytest.raises(DeviceError):
        capture_point(CroppingCamera(flat(1.0e5)), SETTINGS, DarkFrameCache())
