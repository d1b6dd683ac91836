"""The raw capture path (rig.acquisition.capture): a fake EMVA 1288 camera's frames, metered, merged and
reduced by a `RawCapturer`; the run's dark frames (rig.acquisition.frames); the capture schema
(rig.config.capture)."""

import dataclasses
import re

import numpy as np
import pytest
from hypothesis import given
from hypothesis import settings as hyp_settings
from hypothesis import strategies as st

from repo_paths import ROOT
from rig.acquisition.capture import RawCapturer, fixed_bracket, frames_for_snr
from rig.acquisition.capturer import capturer_for
from rig.acquisition.frames import DarkFrameCache
from rig.config.capture import Capture, CaptureParameters, CaptureSettings
from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.core.values import Frame, SensorInfo, Window
from rig.drivers.interfaces import LuminanceCamera
from rig.physics.hdr import saturation_threshold_dn
from rig.physics.roi import block_means

GAIN_DN_PER_E = 0.25
CAL_CD_M2_PER_DN_S = 0.01
READOUT_S = 0.05
SETTINGS = CaptureSettings(roi_px=40, dark_max_age_s=None)     # no rig clock in most tests: darks never age


def tuned(**changes) -> CaptureSettings:
    """SETTINGS with `changes` (validated)."""
    return CaptureSettings(**{**SETTINGS.model_dump(), **changes})


def capture_point(camera, settings=SETTINGS, clock=None):
    """One point captured and reduced by the capturer the camera gets."""
    return capturer_for(camera, settings, clock).acquire().reduce()


class FakeClock(Clock):
    def __init__(self):
        self.t = 1000.0

    def now(self):
        return self.t

    def sleep(self, seconds):
        self.t += seconds


class FakeCamera(LuminanceCamera):
    """Scene of fixed photo-electron rates (e⁻/s per pixel) seen by an EMVA 1288 sensor."""

    def __init__(self, scene_e_s: np.ndarray, seed: int = 0, dark_e_s: float = 50.0,
                 calibration_u_rel: float = 0.0, clock: FakeClock | None = None):
        self.scene_e_s = scene_e_s
        self.dark_e_s = dark_e_s
        self.clock = clock
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
        if self.clock:
            self.clock.sleep(exposure_s + READOUT_S)
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


def exposures_of(camera, exposure_s: float) -> int:
    """How many light frames the camera took at this exposure time (s, within round-off)."""
    return sum(t == pytest.approx(exposure_s, rel=1e-12) for t, _ in camera.light_calls)


def roi_of(camera, capture):
    rows, cols = camera.full_window().inner(capture.roi_window)
    return camera.scene_e_s[rows, cols]


def test_exposure_puts_the_peak_near_the_target_without_saturating():
    camera = FakeCamera(flat(1.0e5))
    capture = capture_point(camera, SETTINGS)
    assert len(capture.exposures_s) == 1 and capture.saturated_fraction == pytest.approx(0.0, abs=1e-12)
    assert capture.flags == ()
    ideal_s = 0.7 * (saturation_threshold_dn(camera.sensor) - 64) / (1.0e5 * GAIN_DN_PER_E)
    assert 0.6 * ideal_s < capture.exposures_s[0] <= 1.1 * ideal_s
    assert capture.luminance_cd_m2 == pytest.approx(luminance(1.0e5), abs=4 * capture.u_luminance_cd_m2)
    assert capture.roi_window == Window(40, 30, 40, 40) and capture.image_cd_m2 is None
    assert all(window == capture.roi_window for _, window in camera.light_calls + camera.dark_calls)
    assert capture.n_frames == len(camera.light_calls)


def test_a_bright_roi_is_exposed_short_enough():
    camera = FakeCamera(flat(1.0e8))                  # the 2 ms probe collects 10× the full well
    capture = capture_point(camera, SETTINGS)
    assert capture.exposures_s == pytest.approx((2.0 ** -13,), rel=1e-12)   # probe 2⁻⁹ s → 2⁻¹¹ s → 2⁻¹³ s
    assert capture.saturated_fraction == pytest.approx(0.0, abs=1e-12) and capture.flags == ()
    assert capture.luminance_cd_m2 == pytest.approx(luminance(1.0e8), abs=4 * capture.u_luminance_cd_m2)


def test_a_high_dynamic_range_roi_gets_several_exposures_and_an_unbiased_mean():
    checker = np.indices((100, 120)).sum(axis=0) % 2 == 0
    camera = FakeCamera(np.where(checker, 5.0e7, 5.0e5))     # 100:1 within every 10-px block
    capture = capture_point(camera, SETTINGS)
    assert len(capture.exposures_s) >= 2 and capture.flags == ()
    assert capture.saturated_fraction == pytest.approx(0.5)
    truth = luminance(roi_of(camera, capture))
    assert capture.luminance_cd_m2 == pytest.approx(truth, abs=4 * capture.u_luminance_cd_m2)
    assert capture.u_luminance_cd_m2 < 0.002 * truth


def test_a_dim_roi_gets_the_longest_exposure_and_is_flagged():
    camera = FakeCamera(flat(0.0))
    capture = capture_point(camera, SETTINGS)
    assert capture.exposures_s == pytest.approx((10.0,), rel=1e-12) and "low_signal" in capture.flags
    assert exposures_of(camera, 10.0) == 1                       # averaging could not help: not tried
    assert capture.luminance_cd_m2 == pytest.approx(0.0, abs=4 * capture.u_luminance_cd_m2)


def test_a_roi_saturated_at_the_shortest_exposure_is_flagged():
    camera = FakeCamera(flat(1.0e10))
    capture = capture_point(camera, SETTINGS)
    assert capture.exposures_s == pytest.approx((1e-4,), rel=1e-12) and "roi_saturated" in capture.flags
    assert capture.saturated_fraction == pytest.approx(1.0, abs=1e-12)
    assert np.isfinite(capture.luminance_cd_m2) and capture.luminance_cd_m2 < luminance(1.0e10)


def test_max_exposures_bounds_the_bracket():
    camera = FakeCamera(flat(1.0e10))
    capture_point(camera, tuned(max_exposures=2))
    assert len({t for t, _ in camera.light_calls}) == 2


def test_darks_are_reused_across_points():
    camera = FakeCamera(flat(1.0e8))
    capturer = RawCapturer(camera, SETTINGS)
    capturer.acquire().reduce()
    taken = capturer.darks.n_taken
    capturer.acquire().reduce()
    assert capturer.darks.n_taken == taken == len(camera.dark_calls) == 1


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
@given(exposure_s=st.floats(1e-6, 100.0), max_exposure_s=st.sampled_from([10.0, 15.0]))
def test_snap_is_idempotent_and_stays_in_range(exposure_s, max_exposure_s):
    """15 s is no rung of the ladder: the longest exposure must still snap to itself."""
    sensor = dataclasses.replace(FakeCamera(flat(0.0, (2, 2))).sensor, max_exposure_s=max_exposure_s)
    snapped = DarkFrameCache().snap(exposure_s, sensor)
    assert sensor.min_exposure_s <= snapped <= sensor.max_exposure_s
    # exact on purpose: ladder exposures are the dark cache's dictionary keys, so snap must be a projection
    assert DarkFrameCache().snap(snapped, sensor) == snapped
    if sensor.min_exposure_s * 1.06 < exposure_s < sensor.max_exposure_s / 1.06:
        assert abs(np.log2(snapped / exposure_s)) <= 1 / 12 + 1e-12


def test_frame_averaging_and_full_frame():
    camera = FakeCamera(flat(1.0e5))
    settings = tuned(frames_per_exposure=3, full_frame=True)
    capture = capture_point(camera, settings)
    merged_s = capture.exposures_s[0]
    assert capture.image_cd_m2.shape == (100, 120)
    # the probes metered the ROI's window (margin 0 px) only; the exposure they chose was read whole, 3 times
    probes = [call for call in camera.light_calls if call[1] != camera.full_window()]
    assert probes and {window for _, window in probes} == {Window(40, 30, 40, 40)}
    assert camera.light_calls[len(probes):] == [(merged_s, camera.full_window())] * 3
    assert capture.n_frames == len(camera.light_calls)
    rows, cols = camera.full_window().inner(capture.roi_window)
    assert capture.luminance_cd_m2 == pytest.approx(capture.image_cd_m2[rows, cols].mean())


def test_a_points_numbers_do_not_depend_on_whether_its_image_is_saved():
    """The ROI's numbers come from the ROI's merge; the whole-frame merge feeds the saved image only."""
    camera = FakeCamera(flat(1.0e5))
    acq = RawCapturer(camera, tuned(full_frame=True)).acquire()
    with_image = acq.reduce()
    without = dataclasses.replace(acq, settings=acq.settings.model_copy(update={"full_frame": False})).reduce()
    assert with_image.image_cd_m2 is not None and without.image_cd_m2 is None
    for field in (f for f in dataclasses.fields(without) if f.name != "image_cd_m2"):
        a, b = getattr(with_image, field.name), getattr(without, field.name)
        if isinstance(b, np.ndarray):                    # the ROI's block pattern
            assert np.array_equal(a, b), field.name
            continue
        assert a == (pytest.approx(b, rel=1e-12) if isinstance(b, float) else b), field.name


def test_window_margin_grows_the_read_window_only():
    camera = FakeCamera(flat(1.0e5))
    capture = capture_point(camera, tuned(window_margin_px=5))
    assert capture.roi_window == Window(40, 30, 40, 40)
    assert {window for _, window in camera.light_calls} == {Window(35, 25, 50, 50)}


def test_calibration_uncertainty_is_combined():
    camera = FakeCamera(flat(1.0e5), calibration_u_rel=0.02)
    capture = capture_point(camera, SETTINGS)
    assert 0.02 < capture.u_luminance_cd_m2 / capture.luminance_cd_m2 < 0.021


def test_bad_settings_and_bad_frames_are_refused():
    with pytest.raises(ValueError, match="target_fraction"):
        CaptureSettings(target_fraction=1.5)
    with pytest.raises(ValueError, match="mode .*adaptive, fixed_bracket"):
        CaptureSettings(mode="hdr")
    with pytest.raises(ValueError, match="max_frames .*frames_per_exposure"):
        CaptureSettings(frames_per_exposure=4, max_frames=2)
    with pytest.raises(ValueError, match="dark_max_age_s"):
        CaptureSettings(dark_max_age_s=0.0)
    with pytest.raises(ValueError, match="roi_px"):
        capture_point(FakeCamera(flat(1.0, (30, 30))), SETTINGS)

    class CroppingCamera(FakeCamera):
        def capture(self, exposure_s, window=None):
            frame = super().capture(exposure_s, window)
            return dataclasses.replace(frame, pixels_dn=frame.pixels_dn[1:])

    with pytest.raises(DeviceError):
        capture_point(CroppingCamera(flat(1.0e5)), SETTINGS)


def test_adaptive_needs_fewer_exposures_and_less_time_than_the_fixed_bracket_and_both_are_unbiased():
    captures = {}
    for mode in ("adaptive", "fixed_bracket"):
        camera = FakeCamera(flat(1.0e5), seed=7)
        capturer = RawCapturer(camera, tuned(mode=mode))
        capturer.acquire()                                     # first point: takes the darks
        camera.light_calls.clear()
        cap = capturer.acquire().reduce()
        assert cap.n_darks == 0 and cap.capture_time_s == pytest.approx(sum(t for t, _ in camera.light_calls))
        assert cap.luminance_cd_m2 == pytest.approx(luminance(1.0e5), abs=4 * cap.u_luminance_cd_m2)
        assert cap.flags == ()
        captures[mode] = cap
    adaptive, fixed = captures["adaptive"], captures["fixed_bracket"]
    assert len(adaptive.exposures_s) == 1 and len(fixed.exposures_s) == 5
    assert adaptive.n_frames < fixed.n_frames and adaptive.capture_time_s < 0.25 * fixed.capture_time_s


def test_fixed_bracket_is_five_exposures_one_stop_apart_centred_on_the_metered_one():
    camera = FakeCamera(flat(1.0e5))
    cap = capture_point(camera, tuned(mode="fixed_bracket"))
    adaptive = capture_point(FakeCamera(flat(1.0e5)), SETTINGS)
    assert len(cap.exposures_s) == 5
    np.testing.assert_allclose(np.diff(np.log2(cap.exposures_s)), 1.0, atol=1e-9)
    assert cap.exposures_s[2] == pytest.approx(adaptive.exposures_s[0], rel=1e-12)
    assert cap.saturated_fraction == pytest.approx(1.0, abs=1e-12)     # the longest clip, are left out
    assert "roi_saturated" not in cap.flags


@pytest.mark.parametrize("centre_s", [1e-4, 3e-3, 10.0])
def test_fixed_bracket_is_shifted_into_the_sensor_range_keeping_its_count(centre_s):
    sensor, darks = FakeCamera(flat(0.0, (2, 2))).sensor, DarkFrameCache()
    bracket = fixed_bracket(darks.snap(centre_s, sensor), tuned(mode="fixed_bracket"), darks, sensor)
    assert len(bracket) == 5 and sensor.min_exposure_s <= bracket[0] and bracket[-1] <= sensor.max_exposure_s
    np.testing.assert_allclose(np.diff(np.log2(bracket)), 1.0, atol=1 / 6)     # within a ladder step at the ends
    assert all(darks.snap(t, sensor) == t for t in bracket)         # exact: ladder rungs (dark cache keys)


def test_frame_averaging_reaches_the_target_snr_on_a_dark_scene_within_max_frames():
    settings = tuned(target_snr=50.0)
    camera = FakeCamera(flat(2.0))                      # 20 e⁻ in 10 s over 500 e⁻ of dark current
    cap = capture_point(camera, settings)
    averaged = exposures_of(camera, 10.0)
    assert cap.exposures_s == pytest.approx((10.0,), rel=1e-12) and 1 < averaged < settings.max_frames
    assert cap.luminance_cd_m2 / cap.u_noise_cd_m2 >= 50.0
    assert cap.n_darks >= averaged                      # the dark's noise is averaged alike
    assert cap.luminance_cd_m2 == pytest.approx(luminance(2.0), abs=4 * cap.u_luminance_cd_m2)

    camera = FakeCamera(flat(2.0))
    cap = capture_point(camera, tuned(target_snr=50.0, max_frames=3))
    assert exposures_of(camera, 10.0) == 3 and cap.luminance_cd_m2 / cap.u_noise_cd_m2 < 50.0


def test_frames_for_snr():
    """Target SNR 10 on a mean of 10: the variance must fall to 1."""
    settings = tuned(target_snr=10.0, max_frames=16, min_snr=2.0)

    def frame_count(var_frames, var_dark, m, n=1, mean=10.0):
        return frames_for_snr(mean, var_frames, var_dark, n, m, settings)

    assert frame_count(0.5, 0.0, 1) == 1                                   # already there
    assert frame_count(4.0, 0.0, 1) == 4                                   # variance ∝ 1/n
    assert frame_count(2.0, 2.0, 1) == 4                                   # darks topped up alike
    assert frame_count(2.0, 0.5, 8) == 4 and frame_count(2.0, 0.5, 1) == 3   # 8 darks do not shrink before n > 8
    assert frame_count(40.0, 0.0, 1) == 16                                 # out of reach: max_frames
    assert frame_count(40.0, 0.0, 2, n=2, mean=1.0) == 2                   # hopeless (< min_snr): no averaging


def test_darks_are_reused_until_too_old_on_the_rig_clock():
    clock = FakeClock()
    camera, settings = FakeCamera(flat(1.0e5), clock=clock), tuned(dark_max_age_s=100.0)
    capturer = RawCapturer(camera, settings, clock)        # the run's clock, handed to the capturer
    first = capturer.acquire().reduce()
    assert first.n_darks == 1
    calls = camera.light_calls + camera.dark_calls
    assert first.capture_time_s == pytest.approx(sum(t + READOUT_S for t, _ in calls))
    clock.sleep(50.0)
    assert capturer.acquire().reduce().n_darks == 0
    clock.sleep(60.0)                                    # the dark is now 110 s old
    assert capturer.acquire().reduce().n_darks == 1
    assert len(camera.dark_calls) == 2
    with pytest.raises(ValueError, match="clock"):
        capture_point(camera, settings)


def test_a_short_dark_stack_is_topped_up_and_keeps_its_age():
    clock = FakeClock()
    camera, darks = FakeCamera(flat(0.0), clock=clock), DarkFrameCache(clock=clock)
    t, roi = darks.snap(0.01, camera.sensor), Window(10, 10, 20, 20)
    first = darks.get(camera, t, roi, max_age_s=10.0)
    clock.sleep(6.0)
    topped = darks.get(camera, t, roi, frames=3, max_age_s=10.0)
    assert topped.shape == (3, 20, 20) and np.array_equal(topped[0], first[0]) and darks.n_taken == 3
    clock.sleep(6.0)
    assert darks.get(camera, t, roi, max_age_s=10.0).shape == (1, 20, 20) and darks.n_taken == 4


def test_texture_and_noise_components():
    flat_cap = capture_point(FakeCamera(flat(1.0e5)), SETTINGS)
    assert flat_cap.u_texture_cd_m2 < min(2 * flat_cap.u_noise_cd_m2, 1e-3 * flat_cap.luminance_cd_m2)
    assert 0 < flat_cap.u_dark_cd_m2 < flat_cap.u_noise_cd_m2

    rng = np.random.default_rng(3)
    grains = 1.0e5 * (1 + 0.1 * rng.standard_normal((10, 12)))
    camera = FakeCamera(np.kron(grains, np.ones((10, 10))))    # 10-px grains on the block grid
    cap = capture_point(camera, SETTINGS)
    blocks = block_means(roi_of(camera, cap)) * GAIN_DN_PER_E * CAL_CD_M2_PER_DN_S
    texture = blocks.std(ddof=1) / np.sqrt(blocks.size)
    assert cap.u_texture_cd_m2 == pytest.approx(texture, rel=0.05) and cap.u_texture_cd_m2 > 10 * cap.u_noise_cd_m2
    assert cap.u_luminance_cd_m2 ** 2 == pytest.approx(cap.u_texture_cd_m2 ** 2 + cap.u_noise_cd_m2 ** 2)


def test_a_camera_that_cannot_read_windows_is_cropped():
    class FullFrameCamera(FakeCamera):
        def _expose(self, rate_e_s, exposure_s, window, dark):
            return super()._expose(rate_e_s, exposure_s, self.full_window(), dark)

    cap = capture_point(FullFrameCamera(flat(1.0e5)), SETTINGS)
    assert cap.roi_window == Window(40, 30, 40, 40) and cap.image_cd_m2 is None and cap.flags == ()
    assert cap.luminance_cd_m2 == pytest.approx(luminance(1.0e5), abs=4 * cap.u_luminance_cd_m2)


def test_one_capture_schema_with_the_documented_defaults():
    """The campaign's `capture` section and a run's settings declare each parameter once: the defaults agree
    (they did not: dark_max_age_s 1800 vs None) and are docs/campaign.md's; only the section has save_images,
    only the settings full_frame and the window margin."""
    shared = set(CaptureParameters.model_fields)
    section, settings = Capture(), CaptureSettings()
    assert len(shared) == 13 and all(getattr(section, k) == getattr(settings, k) for k in shared)
    assert set(Capture.model_fields) - shared == {"save_images"}
    assert set(CaptureSettings.model_fields) - shared == {"full_frame", "window_margin_px"}
    rows = re.findall(r"^\| `capture\.(\w+)` \| ([^|]+) \|", (ROOT / "docs" / "campaign.md").read_text(), re.M)
    documented = {key: default.strip() for key, default in rows}
    assert set(documented) == set(Capture.model_fields)
    for key, default in documented.items():
        value = getattr(section, key)
        assert (default == str(value).lower()) if isinstance(value, (bool, str)) else float(default) == value, key


def test_the_capture_path_is_chosen_once_per_capturer():
    """A raw camera gets a RawCapturer, whose acquisitions say themselves whether they clipped; the camera's
    kind is not asked again per point."""
    camera = FakeCamera(flat(1.0e10))
    capturer = capturer_for(camera, SETTINGS)
    assert isinstance(capturer, RawCapturer) and capturer.roi == Window(40, 30, 40, 40)
    clipped, dim = capturer.acquire(), RawCapturer(FakeCamera(flat(1.0e5)), SETTINGS).acquire()
    assert clipped.clipped and not dim.clipped
    assert "roi_saturated" in clipped.reduce().flags


def test_the_probe_reads_the_roi_alone_and_scales_to_the_usable_range():
    camera = FakeCamera(flat(1.0e7))
    peak, realised_s = RawCapturer(camera, SETTINGS).probe(1e-3)
    assert camera.light_calls == [(1e-3, Window(40, 30, 40, 40))] and realised_s == 1e-3
    usable = saturation_threshold_dn(camera.sensor) - 64.0
    assert peak == pytest.approx(1.0e7 * 1e-3 * GAIN_DN_PER_E / usable, rel=0.05)
