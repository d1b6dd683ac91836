"""GenICam driver (rig.drivers.genicam) against pylon's camera emulation: a real GenICam device, no hardware.

`PYLON_CAMEMU=2` makes pylon enumerate two emulated cameras, serials 0815-0000 and 0815-0001
(pylon Camera Software Suite documentation, "Camera Emulation"); it must be set before pypylon
loads the transport layers. What these tests rely on was read off the emulation of pypylon 26.9:
a 4096×4096 sensor, ROI increments of 1, ExposureTime 1 µs … 10 s in steps of 0.1 µs, Gain
0 … 48 dB, BlackLevel 0 … 1023, trigger selectable on Line1, and its test image 1 in Mono12
is 16·(x + y) mod 4096 at sensor column x, row y whatever the region read.
"""

import os
import sys

import numpy as np
import pytest

from rig.acquisition.capturer import capturer_for
from rig.config.capture import CaptureSettings
from rig.config.rigdevices import CameraDevice
from rig.config.rigfile import CameraConfig, RigConfigError
from rig.core.errors import DeviceError
from rig.core.values import Window
from rig.devices import camera_class
from rig.drivers.genicam import GenICamCamera, RoiSteps

# before pypylon loads (rig.drivers.genicam imports it only when a camera is opened)
os.environ["PYLON_CAMEMU"] = "2"
pytest.importorskip("pypylon.pylon", reason="pypylon (Basler pylon runtime) has no wheel for this platform; "
                                            "install rig[genicam] to test the GenICam driver")

SENSOR = 4096
FIRST, SECOND = "0815-0000", "0815-0001"
CONFIG = CameraConfig(width_px=SENSOR, height_px=SENSOR, bit_depth=12, black_level_dn=64.0,
                      min_exposure_s=1e-4, max_exposure_s=15.0)
CONFIG16 = CONFIG.model_copy(update={"bit_depth": 16})


def emulated_image(window: Window) -> np.ndarray:
    """The emulation's test image 1 in Mono12 over `window` (sensor coordinates)."""
    rows, cols = np.mgrid[window.y0:window.y0 + window.height, window.x0:window.x0 + window.width]
    return (16 * (rows + cols) % 4096).astype(np.uint16)


@pytest.fixture
def open_camera():
    """Opens emulated cameras showing test image 1 and closes them after the test."""
    opened = []

    def open_(config=CONFIG, **options):
        camera = GenICamCamera(config, **options)
        opened.append(camera)
        camera.camera.TestImageSelector.Value = "Testimage1"
        return camera

    yield open_
    for camera in opened:
        camera.close()


def test_opens_the_first_camera_and_takes_the_sensor_from_it(open_camera):
    cam = open_camera()
    assert FIRST in cam.identity() and "Mono12" in cam.identity()
    s = cam.sensor
    assert (s.width_px, s.height_px, s.bit_depth) == (SENSOR, SENSOR, 12)
    assert s.gain_dn_per_e == pytest.approx(CONFIG.gain_dn_per_e)
    assert s.black_level_dn == 64.0 and s.read_noise_e == CONFIG.read_noise_e
    # the rig file's 1e-4 … 15 s, clipped to the camera's 1 µs … 10 s
    assert s.min_exposure_s == pytest.approx(1e-4) and s.max_exposure_s == pytest.approx(10.0)
    assert (cam.camera.ExposureAuto.Value, cam.camera.GainAuto.Value, cam.camera.TriggerMode.Value) == \
        ("Off", "Off", "Off")


def test_serial_chooses_the_camera(open_camera):
    assert SECOND in open_camera(serial=SECOND).identity()


def test_an_absent_serial_names_the_cameras_seen():
    with pytest.raises(DeviceError, match=f"no GenICam camera with serial 'nope'.*{FIRST}") as err:
        GenICamCamera(CONFIG, serial="nope")
    assert not err.value.transient


def test_pixel_format_follows_the_rig_files_bit_depth(open_camera):
    cam = open_camera(CONFIG16)
    assert cam.camera.PixelFormat.Value == "Mono16" and cam.sensor.bit_depth == 16
    assert cam.capture(1e-3, Window(0, 0, 8, 4)).pixels_dn.dtype == np.uint16


@pytest.mark.parametrize("config, pixel_format, message", [
    (CONFIG16, "Mono12", "Mono12 gives 12-bit DN, the rig file's camera section says bit_depth 16"),
    (CONFIG, "Mono14", "'Mono14' is not offered; the camera's monochrome formats: Mono8, Mono10, Mono12, Mono16"),
    (CONFIG.model_copy(update={"bit_depth": 14}), "auto", "'Mono14' is not offered"),
])
def test_a_pixel_format_the_rig_file_cannot_use_is_refused(config, pixel_format, message):
    with pytest.raises(DeviceError, match=message):
        GenICamCamera(config, pixel_format=pixel_format)


def test_a_sensor_of_another_size_than_the_rig_files_is_refused():
    with pytest.raises(DeviceError, match="sensor is 4096×4096 px, the rig file's camera section says 1390×1040"):
        GenICamCamera(CameraConfig())


def test_gain_and_black_level_are_fixed(open_camera):
    cam = open_camera(gain=6.0, black_level=100)
    assert cam.camera.Gain.Value == pytest.approx(6.0, abs=1e-3)
    assert cam.camera.BlackLevel.Value == pytest.approx(100)
    meta = cam.capture(1e-3, Window(0, 0, 8, 4)).meta
    assert meta["gain"] == pytest.approx(6.0, abs=1e-3) and meta["black_level"] == pytest.approx(100)


def test_a_value_the_camera_refuses_is_a_device_error():
    with pytest.raises(DeviceError, match="setting BlackLevel to 5000.* failed: .*1023") as err:
        GenICamCamera(CONFIG, black_level=5000)
    assert not err.value.transient


def test_exposure_is_set_in_microseconds_and_read_back(open_camera):
    cam = open_camera()
    realised = cam.set_exposure(1.23456e-3)
    assert realised == pytest.approx(cam.camera.ExposureTime.Value * 1e-6)
    assert realised == pytest.approx(1.23456e-3, abs=1e-6)
    assert cam.set_exposure(20.0) == pytest.approx(10.0)          # clipped to the camera's range
    assert cam.set_exposure(1e-9) == pytest.approx(1e-6)
    frame = cam.capture(2.5e-3, Window(0, 0, 8, 4))
    assert frame.exposure_s == pytest.approx(2.5e-3, abs=1e-7)
    assert frame.exposure_s == pytest.approx(cam.camera.ExposureTime.Value * 1e-6)
    for bad in (0.0, -1.0, float("nan")):
        with pytest.raises(DeviceError, match="not a positive number"):
            cam.set_exposure(bad)


def test_full_frame_grab(open_camera):
    cam = open_camera()
    frame = cam.capture(1e-3)
    assert frame.window == Window(0, 0, SENSOR, SENSOR) and not frame.dark
    assert frame.pixels_dn.dtype == np.uint16 and frame.pixels_dn.shape == (SENSOR, SENSOR)
    np.testing.assert_array_equal(frame.pixels_dn[:64, :64], emulated_image(Window(0, 0, 64, 64)))


def test_a_window_on_the_grid_is_read_as_it_is(open_camera):
    cam = open_camera()
    window = Window(10, 5, 64, 32)
    frame = cam.capture(1e-3, window)
    assert frame.window == window and frame.meta["region"] == window
    assert (cam.camera.OffsetX.Value, cam.camera.OffsetY.Value, cam.camera.Width.Value, cam.camera.Height.Value) \
        == (10, 5, 64, 32)
    np.testing.assert_array_equal(frame.pixels_dn, emulated_image(window))


def test_a_window_off_the_grid_is_grown_and_cropped_back(open_camera):
    cam = open_camera()
    # the emulation's increments are 1: a coarser grid, as real sensors have, stands in for them
    cam.roi = RoiSteps(SENSOR, SENSOR, min_width=16, min_height=8, width_inc=16, height_inc=4, x_inc=8, y_inc=2)
    window = Window(13, 7, 30, 3)
    frame = cam.capture(1e-3, window)
    assert frame.meta["region"] == Window(8, 6, 48, 8)
    assert (cam.camera.Width.Value, cam.camera.Height.Value) == (48, 8)
    assert frame.window == window and frame.pixels_dn.shape == (3, 30)
    np.testing.assert_array_equal(frame.pixels_dn, emulated_image(window))


@pytest.mark.parametrize("window, region", [
    (Window(0, 0, 64, 16), Window(0, 0, 64, 16)),               # on the grid
    (Window(3, 1, 1, 1), Window(0, 0, 16, 8)),                  # grown to the smallest region
    (Window(4090, 4093, 6, 3), Window(4080, 4088, 16, 8)),       # moved back from the sensor's edge
])
def test_roi_grid(window, region):
    steps = RoiSteps(SENSOR, SENSOR, min_width=16, min_height=8, width_inc=16, height_inc=4, x_inc=8, y_inc=4)
    assert steps.fit(window) == region


def test_a_window_outside_the_sensor_is_refused(open_camera):
    with pytest.raises(DeviceError, match="not inside the 4096×4096 sensor"):
        open_camera().capture(1e-3, Window(4000, 0, 200, 10))


def test_a_frame_that_does_not_come_is_a_transient_timeout(open_camera):
    cam = open_camera(grab_timeout_s=0.05)
    cam.camera.TriggerMode.Value = "On"            # waits for a hardware trigger that never comes
    cam.camera.TriggerSource.Value = "Line1"
    with pytest.raises(DeviceError, match="grabbing a 0.001 s frame .* timed out") as err:
        cam.capture(1e-3, Window(0, 0, 8, 4))
    assert err.value.transient


def test_dark_frames_need_the_operators_darkness(open_camera):
    with pytest.raises(DeviceError, match="no shutter"):
        open_camera().capture_dark(1e-3)
    frame = open_camera(serial=SECOND, dark_frames="same").capture_dark(1e-3, Window(0, 0, 8, 4))
    assert frame.dark and frame.pixels_dn.shape == (4, 8)
    with pytest.raises(DeviceError, match="dark_frames is 'lens_cap'"):
        GenICamCamera(CONFIG, dark_frames="lens_cap")


def test_rigs_capture_reads_the_roi_through_it(open_camera):
    # the emulation's picture does not depend on exposure, so its darks cancel it: no signal, but every
    # frame is the ROI's window at a realised exposure inside the clipped range
    cam = open_camera(dark_frames="same")
    cap = capturer_for(cam, CaptureSettings(roi_px=40, dark_max_age_s=None)).acquire().reduce()
    assert cap.roi_window == Window.centred(SENSOR, SENSOR, 40, 40)
    assert cap.n_frames >= 1 and cap.n_darks >= 1
    low, high = cam.sensor.min_exposure_s, cam.sensor.max_exposure_s
    assert all(low * (1 - 1e-9) <= t <= high * (1 + 1e-9) for t in cap.exposures_s)
    assert cap.luminance_cd_m2 == pytest.approx(0.0, abs=1e-9) and "low_signal" in cap.flags


def test_loaded_as_a_plug_in_with_its_options(open_camera):
    options = {"serial": SECOND, "gain": 3.0, "black_level": 20, "grab_timeout_s": 2.0, "dark_frames": "same"}
    dev = CameraDevice(driver="python:rig.drivers.genicam:GenICamCamera", options=options)
    cls = camera_class(dev, CONFIG)
    assert cls is GenICamCamera
    cam = cls(CONFIG, **dev.options)
    try:
        assert SECOND in cam.identity() and cam.gain == pytest.approx(3.0, abs=1e-3)
    finally:
        cam.close()
    with pytest.raises(RigConfigError, match="does not take"):
        camera_class(CameraDevice(driver=dev.driver, options={"exposure": 1}), CONFIG)
    GenICamCamera.from_rig(clock=None, settings=CONFIG, serial=FIRST).close()


def test_closing_twice_is_harmless():
    cam = GenICamCamera(CONFIG)
    cam.close()
    cam.close()


def test_without_pypylon_the_error_says_how_to_install(monkeypatch):
    monkeypatch.setitem(sys.modules, "pypylon.pylon", None)     # import of it fails
    with pytest.raises(DeviceError, match=r"needs pypylon: pip install 'rig\[genicam\]'"):
        GenICamCamera(CONFIG)
