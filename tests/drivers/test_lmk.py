"""TechnoTeam LMK driver (rig.drivers.lmk) against a fake LabSoft COM server.

The fake implements the documented LMKAxServer methods the driver uses, as win32com presents
them: input arguments only, an int error code, or (code, out1, …) for by-reference outputs.
Sources (public): the LMKAxServer class reference (2010) in github fglichttechnik/TechnoTeam-LMK-MATLAB,
Documentation/activexserver, and its ActiveXWrapper/*.m (iCaptureGetLastInfo's twelve outputs,
iImageGetSize's first/last line/column); luxpy toolboxes/technoteamlmk/TechnoTeamLMK.py (iOpen
answering 137363456 while LabSoft's licence dialog is open; `lmk.iSetIntegrationTime(0.1, 0)` →
`(0, ≈0.1)`); PTB's stand-alone wrapper (C. Schrader: (code, outputs) tuples, iGetErrorInformation()[1],
the dump reshaped to (l1 − l0 + 1, c1 − c0 + 1) float32 rows).
"""

import sys
import types

import numpy as np
import pytest

from rig.acquisition.capturer import capturer_for
from rig.config.capture import CaptureSettings
from rig.config.rigdevices import CameraDevice
from rig.config.rigfile import CameraConfig, RigConfigError
from rig.core.errors import DeviceError
from rig.core.values import Window
from rig.devices import camera_class
from rig.drivers import lmk
from rig.drivers.lmk import LmkCamera

WIDTH, HEIGHT = 120, 80
CONFIG = CameraConfig(width_px=WIDTH, height_px=HEIGHT, min_exposure_s=1e-4, max_exposure_s=15.0,
                      calibration_u_rel=0.025)
LICENCE_DIALOG = 137363456
#: Arbitrary codes of the fake (LabSoft's own numbers are not public) and their texts.
ERROR_TEXTS = {LICENCE_DIALOG: "Cannot open LabSoft", 4711: "Camera not connected", 815: "Invalid image region"}


class FakeLmkServer:
    """LabSoft's `lmk4.LMKAxServer` as win32com shows it, over a fixed luminance image (cd/m²)."""

    def __init__(self, luminance=None, *, is_open=False, min_s=1e-5, max_s=10.0, overflow_percent=0.0,
                 load_percent=40.0, success=1, fail=None, close_code=0, short_dump=False, size=(WIDTH, HEIGHT)):
        self.luminance = (np.arange(WIDTH * HEIGHT, dtype=np.float32).reshape(HEIGHT, WIDTH)
                          if luminance is None else np.asarray(luminance, dtype=np.float32))
        self.is_open, self.min_s, self.max_s = is_open, min_s, max_s
        self.overflow_percent, self.load_percent, self.success = overflow_percent, load_percent, success
        self.fail = fail or {}              # method → error code it returns
        self.close_code, self.short_dump, self.size = close_code, short_dump, size
        self.time_s = 0.01
        self.calls: list[tuple] = []
        self.last: tuple = (0, 0, 1, self.time_s, self.time_s)       # algorithm, pictures, max, min
        self.error_text = ""

    def _code(self, method, *args):
        self.calls.append((method, *args))
        code = self.fail.get(method, 0)
        if code:
            self.error_text = ERROR_TEXTS[code]
        return code

    def iIsOpen(self):
        self.calls.append(("iIsOpen",))
        return int(self.is_open)

    def iOpen(self):
        code = self._code("iOpen")
        self.is_open = self.is_open or code == 0
        return code

    def iSetNewCamera2(self, camera, lens):
        return self._code("iSetNewCamera2", camera, lens)

    def iSetNewCamera(self, lens_dir):
        return self._code("iSetNewCamera", lens_dir)

    def iSetIntegrationTime(self, wished_s):
        code = self._code("iSetIntegrationTime", wished_s)
        self.time_s = min(max(round(wished_s / 1e-5) * 1e-5, self.min_s), self.max_s)   # the camera's scale
        return code, self.time_s

    def iGetIntegrationTime(self):
        code = self._code("iGetIntegrationTime")
        return code, self.time_s, self.time_s - 1e-5, self.time_s + 1e-5, self.min_s, self.max_s

    def iSinglePic(self, exposure_s, smear, modulation_hz):
        self.last = (1, 1, exposure_s, exposure_s)
        return self._code("iSinglePic", exposure_s, smear, modulation_hz)

    def iHighDynPic(self, max_s, min_s, factor, smear, modulation_hz):
        self.last = (3, 3, max_s, max_s / factor ** 2)
        return self._code("iHighDynPic", max_s, min_s, factor, smear, modulation_hz)

    def iCaptureGetLastInfo(self):
        algorithm, count, max_s, min_s = self.last
        return (self._code("iCaptureGetLastInfo"), self.success, algorithm, "", "", count, max_s, min_s,
                self.overflow_percent, self.load_percent, "2026-01-01 12:00:00", 0, 0.0)

    def iImageGetSize(self, image):
        width, height = self.size
        return self._code("iImageGetSize", image), 0, height - 1, 0, width - 1, 1

    def iImageGetDumpToMemory(self, image, l0, l1, c0, c1):
        code = self._code("iImageGetDumpToMemory", image, l0, l1, c0, c1)
        last_line = l1 if self.short_dump else l1 + 1     # short_dump: the class reference's formula (no +1)
        return code, self.luminance[l0:last_line, c0:c1 + 1].astype("<f4").tobytes()

    def iGetErrorInformation(self):
        self.calls.append(("iGetErrorInformation",))
        return 0, self.error_text

    def iClose(self, question):
        self.calls.append(("iClose", question))
        if self.close_code > 1:
            self.error_text = ERROR_TEXTS[self.close_code]
        return self.close_code

    def methods(self):
        return [c[0] for c in self.calls]


def camera(server=None, **options):
    return LmkCamera(CONFIG, server=server or FakeLmkServer(), **options)


# -- session ------------------------------------------------------------------------------------
def test_open_starts_labsoft_sets_the_camera_and_reads_the_exposure_range():
    server = FakeLmkServer(min_s=2e-4, max_s=10.0)
    cam = camera(server, camera="dxm2134", lens="oC202517f25")
    assert server.calls == [("iIsOpen",), ("iOpen",), ("iSetNewCamera2", "dxm2134", "oC202517f25"),
                            ("iGetIntegrationTime",)]
    assert (cam.sensor.min_exposure_s, cam.sensor.max_exposure_s) == (2e-4, 10.0)   # narrower of LMK and rig file
    assert cam.sensor.calibration_u_rel == 0.025
    assert cam.identity() == "TechnoTeam LMK dxm2134/oC202517f25"


def test_an_open_labsoft_is_not_reopened_and_a_lens_directory_uses_iSetNewCamera():
    server = FakeLmkServer(is_open=True)
    camera(server, lens_dir=r"C:\LMK\Camera\dxm2134\oC202517f25")
    assert server.methods() == ["iIsOpen", "iSetNewCamera", "iGetIntegrationTime"]


@pytest.mark.parametrize("options", [{"camera": "dxm2134"}, {"camera": "a", "lens": "b", "lens_dir": "c"}])
def test_inconsistent_camera_options_are_refused(options):
    with pytest.raises(DeviceError, match="give camera and lens"):
        camera(**options)


def test_a_prog_id_given_as_server_is_pointed_to_prog_id():
    with pytest.raises(DeviceError, match="name the ProgID with prog_id: 'lmk4.LMKAxServer'"):
        LmkCamera(CONFIG, server="lmk4.LMKAxServer")


def test_the_licence_dialog_code_on_iOpen_is_explained():
    with pytest.raises(DeviceError) as err:
        camera(FakeLmkServer(fail={"iOpen": LICENCE_DIALOG}))
    assert str(err.value) == ("LMK: iOpen returned error code 137363456: Cannot open LabSoft (LabSoft shows a "
                              "dialog (seen with the licence dialog open): close it on the PC and retry)")


@pytest.mark.parametrize(("code", "message"), [(0, None), (1, "LMK: iClose: LabSoft refused to close"),
                                               (4711, "LMK: iClose returned error code 4711: Camera not connected")])
def test_close_asks_no_question_and_reports_refusal_and_errors(code, message):
    server = FakeLmkServer(close_code=code)
    cam = camera(server)
    if message is None:
        cam.close()
    else:
        with pytest.raises(DeviceError, match=message):
            cam.close()
    assert ("iClose", 0) in server.calls


# -- integration time -------------------------------------------------------------------------------
def test_integration_time_is_set_and_read_in_seconds():
    cam = camera()
    assert cam.set_integration_time(0.1000031) == pytest.approx(0.1, abs=1e-9)     # [C] (0, ≈0.1)
    t = cam.integration_time()
    assert (t.current_s, t.min_s, t.max_s) == pytest.approx((0.1, 1e-5, 10.0))
    assert t.previous_s < t.current_s < t.next_s


# -- pictures -----------------------------------------------------------------------------------------
def test_single_picture_reads_the_window_row_by_row():
    server = FakeLmkServer(overflow_percent=0.5, load_percent=63.0)
    cam = camera(server, modulation_hz=50, smear=2)
    window = Window(10, 5, 30, 20)
    image = cam.capture_luminance(0.04, window)
    assert server.calls[-4:] == [("iSinglePic", 0.04, 2, 50.0), ("iCaptureGetLastInfo",), ("iImageGetSize", -2),
                                 ("iImageGetDumpToMemory", -2, 5, 24, 10, 39)]
    assert image.pixels_cd_m2.dtype == np.float32 and image.pixels_cd_m2.shape == (20, 30)
    rows, cols = np.mgrid[5:25, 10:40]
    np.testing.assert_array_equal(image.pixels_cd_m2, rows * WIDTH + cols)       # first line first
    assert (image.window, image.exposures_s, image.algorithm) == (window, (0.04,), "single")
    assert image.overflow_fraction == pytest.approx(0.005) and image.peak_load == pytest.approx(0.63)
    assert image.saturated is None


def test_hdr_picture_reports_its_exposures_longest_first_and_reads_the_full_sensor():
    server = FakeLmkServer()
    image = camera(server).capture_hdr_luminance(2.0, 1e-4, 3.0)
    assert ("iHighDynPic", 2.0, 1e-4, 3.0, 0, 0.0) in server.calls
    assert server.calls[-1] == ("iImageGetDumpToMemory", -2, 0, HEIGHT - 1, 0, WIDTH - 1)
    assert image.algorithm == "high_dynamic"
    assert image.exposures_s == pytest.approx((2.0, 2.0 / 3, 2.0 / 9))
    np.testing.assert_array_equal(image.pixels_cd_m2, server.luminance)


def test_a_dump_one_line_short_as_the_class_reference_formula_would_have_it_is_refused():
    with pytest.raises(DeviceError, match=r"iImageGetDumpToMemory\(0, 9, 0, 9\) gave 90 values, expected 10 lines "
                                          r"× 10 columns \(ends included\)"):
        camera(FakeLmkServer(short_dump=True)).capture_luminance(0.01, Window(0, 0, 10, 10))


def test_an_image_of_another_size_than_the_rig_file_says_is_refused():
    with pytest.raises(DeviceError, match="the luminance image is 1390×1040 px, the rig file's camera section says "
                                          "120×80"):
        camera(FakeLmkServer(size=(1390, 1040))).capture_luminance(0.01)


def test_a_capture_labsoft_reports_unsuccessful_is_refused():
    with pytest.raises(DeviceError, match="iCaptureGetLastInfo reports the single capture failed"):
        camera(FakeLmkServer(success=0)).capture_luminance(0.01)


# -- error codes --------------------------------------------------------------------------------------
ACTIONS = {
    "iSetNewCamera2": lambda server: camera(server, camera="dxm2134", lens="oC202517f25"),
    "iGetIntegrationTime": lambda server: camera(server),
    "iSetIntegrationTime": lambda server: camera(server).set_integration_time(0.1),
    "iSinglePic": lambda server: camera(server).capture_luminance(0.1),
    "iHighDynPic": lambda server: camera(server).capture_hdr_luminance(1.0, 0.0, 3.0),
    "iCaptureGetLastInfo": lambda server: camera(server).capture_luminance(0.1),
    "iImageGetSize": lambda server: camera(server).capture_luminance(0.1),
    "iImageGetDumpToMemory": lambda server: camera(server).capture_luminance(0.1),
}


@pytest.mark.parametrize("method", ACTIONS)
def test_every_error_code_is_a_device_error_with_method_code_and_labsoft_text(method):
    server = FakeLmkServer(fail={method: 4711})
    with pytest.raises(DeviceError) as err:
        ACTIONS[method](server)
    assert str(err.value).endswith(f"{method} returned error code 4711: Camera not connected")
    assert not err.value.transient
    assert server.calls[-1] == ("iGetErrorInformation",)


def test_an_error_without_text_says_so():
    server = FakeLmkServer(fail={"iSinglePic": 4711})
    server.iGetErrorInformation = lambda: (12, "")
    with pytest.raises(DeviceError, match=r"iSinglePic returned error code 4711: \(iGetErrorInformation gave no "):
        camera(server).capture_luminance(0.1)


def test_a_failing_com_call_is_a_device_error_naming_the_method():
    server = FakeLmkServer()

    def broken(*args):
        raise OSError("(-2147023174, 'The RPC server is unavailable.')")
    server.iHighDynPic = broken
    with pytest.raises(DeviceError, match=r"LMK: iHighDynPic failed: OSError: .*RPC server is unavailable"):
        camera(server).capture_hdr_luminance(1.0, 0.0, 3.0)


# -- starting the COM server ----------------------------------------------------------------------------
def test_without_windows_the_driver_says_what_it_needs(monkeypatch):
    monkeypatch.setattr(sys, "platform", "linux")
    with pytest.raises(DeviceError, match="camera: the LMK driver needs LabSoft's COM server on Windows; this is lin"):
        LmkCamera(CONFIG)


def test_without_pywin32_the_driver_names_the_extra(monkeypatch):
    monkeypatch.setattr(sys, "platform", "win32")
    monkeypatch.setitem(sys.modules, "win32com.client", None)        # import fails
    with pytest.raises(DeviceError, match=r"needs pywin32: pip install 'rig\[lmk\]'"):
        LmkCamera(CONFIG)


def test_the_com_server_is_dispatched_by_prog_id(monkeypatch):
    server = FakeLmkServer()
    dispatched = []
    client = types.SimpleNamespace(Dispatch=lambda prog_id: dispatched.append(prog_id) or server)
    monkeypatch.setattr(sys, "platform", "win32")
    monkeypatch.setattr(lmk.importlib, "import_module", lambda name: client)
    LmkCamera(CONFIG)
    assert dispatched == ["lmk4.LMKAxServer.1"]
    assert server.methods()[0] == "iIsOpen"


# -- as a rig camera --------------------------------------------------------------------------------------
def test_the_plugin_loader_accepts_the_driver_with_its_options():
    options = {"camera": "dxm2134", "lens": "oC202517f25", "modulation_hz": 50, "smear": 0}
    dev = CameraDevice(driver="python:rig.drivers.lmk:LmkCamera", options=options)
    assert camera_class(dev, CONFIG) is LmkCamera
    with pytest.raises(RigConfigError, match="constructor does not take"):
        camera_class(CameraDevice(driver="python:rig.drivers.lmk:LmkCamera", options={"lens_directory": "x"}),
                     CONFIG)


def test_a_point_captured_through_the_driver_is_the_roi_mean_of_labsoft_s_image():
    rows, cols = np.indices((HEIGHT, WIDTH))
    luminance = np.where((rows + cols) % 2, 4.1, 3.9).astype(np.float32)   # a pixel checkerboard: the ROI mean is 4
    server = FakeLmkServer(luminance)
    cap = capturer_for(camera(server), CaptureSettings(roi_px=40)).acquire().reduce()
    assert ("iHighDynPic", 10.0, 1e-4, 4.0, 0, 0.0) in server.calls     # longest, shortest, 2 stops apart
    assert server.calls[-1] == ("iImageGetDumpToMemory", -2, 20, 59, 40, 79)
    assert cap.luminance_cd_m2 == pytest.approx(4.0)
    assert cap.exposures_s == pytest.approx((10.0, 2.5, 0.625))
    assert (cap.n_frames, cap.n_darks, cap.flags) == (3, 0, ())
