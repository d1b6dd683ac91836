"""TechnoTeam LMK luminance camera, driven through LabSoft's ActiveX/COM server, as a CalibratedLuminanceCamera.

The API is LabSoft's documented `LMKAxServer` (class reference of 2010 in github
fglichttechnik/TechnoTeam-LMK-MATLAB, Documentation/activexserver; used the same way by
luxpy's toolboxes/technoteamlmk/TechnoTeamLMK.py and PTB's stand-alone wrapper). Every
method returns an int, 0 = OK, else an error code whose text `iGetErrorInformation`
gives; through win32com a method with by-reference arguments returns the tuple
(code, out1, out2, …) and takes only its input arguments. A code is LabSoft's own
verdict, so it is a persistent DeviceError naming the method, the code and the text.

LabSoft calibrates the pictures itself (camera and lens calibration data, its own dark
images), so the camera delivers luminance (cd/m², image −2) and rig takes no dark frames.
Only the window rig asks for is dumped (`iImageGetDumpToMemory`, float32 row by row,
lines l0…l1 and columns c0…c1 inclusive as PTB reads them: the class reference's size
formula omits the +1 on lines; a dump of that shorter size is reported, not reshaped).
Calls block until LabSoft is done; the COM server is started with
`win32com.client.Dispatch(prog_id)` (pywin32, Windows only) unless one is injected.
"""

from __future__ import annotations

import importlib
import sys
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from rig.core.errors import DeviceError
from rig.core.values import LuminanceImage, SensorInfo, Window
from rig.drivers.interfaces import CalibratedLuminanceCamera

PROG_ID = "lmk4.LMKAxServer.1"
#: Image numbers of the API: −3 camera image, −2 luminance image, −1 colour image, ≥ 0 evaluation images.
LUMINANCE_IMAGE = -2
#: iCaptureGetLastInfo's algorithm codes, as the MATLAB wrapper (ActiveXWrapper) names them; the 2010
#: class reference numbers them from 0 = SinglePic. Only reported, never relied on.
ALGORITHMS = {0: "camera", 1: "single", 2: "multi", 3: "high_dynamic", 4: "colour_high_dynamic"}
#: Codes whose cause is known from public use, added to LabSoft's own text.
KNOWN_CODES = {137363456: "LabSoft shows a dialog (seen with the licence dialog open): close it on the PC and retry"}
#: iClose's answers besides 0 = closed: 1 = LabSoft refused (a dialog asked the user), > 1 an error code.
CLOSE_REFUSED = 1


class CameraSection(Protocol):
    """What the driver reads of the rig file's camera section (rig.config.rigfile.CameraConfig)."""

    def sensor_info(self) -> SensorInfo: ...


@dataclass(frozen=True)
class IntegrationTime:
    """`iGetIntegrationTime`'s answer (s): the time set, its neighbours on the camera's scale, and the range."""

    current_s: float
    previous_s: float
    next_s: float
    min_s: float
    max_s: float


@dataclass(frozen=True)
class CaptureInfo:
    """`iCaptureGetLastInfo`'s answer about the last capture."""

    success: bool
    algorithm: str
    pictures: int
    max_time_s: float
    min_time_s: float
    overflow_percent: float
    max_load_percent: float

    def exposures_s(self) -> tuple[float, ...]:
        """Longest first: the reported longest and shortest, the ones between evenly spaced in log time
        (LabSoft reports only the two ends and the count)."""
        if self.pictures <= 1:
            return (self.max_time_s,)
        return tuple(float(t) for t in np.geomspace(self.max_time_s, self.min_time_s, self.pictures))


def dispatch(prog_id: str) -> Any:
    """LabSoft's COM server; a DeviceError if this is not Windows, pywin32 is missing or the server does not start."""
    if sys.platform != "win32":
        raise DeviceError("camera", f"the LMK driver needs LabSoft's COM server on Windows; this is {sys.platform}")
    try:
        client = importlib.import_module("win32com.client")
    except ImportError:
        raise DeviceError("camera", "the LMK driver needs pywin32: pip install 'rig[lmk]'") from None
    try:
        return client.Dispatch(prog_id)
    except Exception as exc:       # pywintypes.com_error: not registered, LabSoft not installed
        raise DeviceError("camera", f"cannot start COM server {prog_id!r} (is LabSoft installed and licensed?): "
                                    f"{exc}") from None


class LmkCamera(CalibratedLuminanceCamera):
    """A TechnoTeam LMK through LabSoft: a rig camera plug-in, `python:rig.drivers.lmk:LmkCamera`.

    Options: `camera` and `lens` (calibration data names, e.g. "dxm2134" and "oC202517f25": opened with
    `iSetNewCamera2`) or `lens_dir` (a lens calibration directory: `iSetNewCamera`), neither to keep
    LabSoft's current camera; `modulation_hz` (0: the light is not modulated) and `smear` (smear
    images, 0: none) for every capture; `prog_id`; `server` injects a COM object (tests).
    """

    def __init__(self, camera_config: CameraSection, *, camera: str = "", lens: str = "", lens_dir: str = "",
                 modulation_hz: float = 0.0, smear: int = 0, prog_id: str = PROG_ID, server: Any = None):
        if bool(camera) != bool(lens) or (camera and lens_dir):
            raise DeviceError("camera", "LMK options: give camera and lens (iSetNewCamera2), or lens_dir "
                                        "(iSetNewCamera), or none of them")
        self.modulation_hz = float(modulation_hz)
        self.smear = int(smear)
        self._name = f"LMK {camera}/{lens}" if camera else f"LMK {lens_dir}" if lens_dir else "LMK"
        if isinstance(server, str):
            raise DeviceError("camera", f"LMK option server is the COM object itself (tests); name the ProgID "
                                        f"with prog_id: {server!r}")
        self.server = server if server is not None else dispatch(prog_id)
        if self._invoke("iIsOpen") != 1:        # its answer is 0/1, not an error code
            self._call("iOpen")
        if camera:
            self._call("iSetNewCamera2", camera, lens)
        elif lens_dir:
            self._call("iSetNewCamera", lens_dir)
        limits = self.integration_time()
        sensor = camera_config.sensor_info()
        self.sensor = replace(sensor, min_exposure_s=max(sensor.min_exposure_s, limits.min_s),
                              max_exposure_s=min(sensor.max_exposure_s, limits.max_s))

    # -- the COM calls ----------------------------------------------------------------------------
    def _invoke(self, method: str, *args: Any) -> Any:
        try:
            return getattr(self.server, method)(*args)
        except Exception as exc:     # pywintypes.com_error and the like: the call itself failed
            raise DeviceError(self._name, f"{method} failed: {type(exc).__name__}: {exc}") from None

    def _call(self, method: str, *args: Any) -> tuple:
        """Call `method` with its input arguments; its by-reference outputs, or DeviceError on a code ≠ 0."""
        answer = self._invoke(method, *args)
        code, outputs = (answer, ()) if isinstance(answer, int) else (answer[0], tuple(answer[1:]))
        if code != 0:
            raise DeviceError(self._name, f"{method} returned error code {code}: {self._error_text(code)}")
        return outputs

    def _error_text(self, code: int) -> str:
        answer = self._invoke("iGetErrorInformation")
        if isinstance(answer, int) or answer[0] != 0:
            text = "(iGetErrorInformation gave no text)"
        else:
            text = str(answer[1]).strip() or "(no text)"
        return f"{text} ({KNOWN_CODES[code]})" if code in KNOWN_CODES else text

    # -- the camera -----------------------------------------------------------------------------
    @classmethod
    def from_rig(cls, *, clock: Any, settings: CameraSection, **options: Any) -> LmkCamera:
        """The rig-file contract (rig.drivers.registry): `settings` is the rig file's `camera` section;
        LabSoft's calls block, so no clock is needed."""
        return cls(settings, **options)

    def identity(self) -> str:
        return f"TechnoTeam {self._name}"

    def set_integration_time(self, wished_s: float) -> float:
        """Set the integration time; the time the camera realised (s)."""
        (realised,) = self._call("iSetIntegrationTime", float(wished_s))
        return float(realised)

    def integration_time(self) -> IntegrationTime:
        return IntegrationTime(*(float(v) for v in self._call("iGetIntegrationTime")))

    def last_capture(self) -> CaptureInfo:
        """`iCaptureGetLastInfo`: success, algorithm, filters, pictures, max/min time, overflow %, load %, …"""
        info = self._call("iCaptureGetLastInfo")
        if len(info) < 9:
            raise DeviceError(self._name, f"iCaptureGetLastInfo answered {len(info)} values, expected 12")
        success, algorithm, _grey, _colour, count, max_t, min_t, overflow, load = info[:9]
        return CaptureInfo(success=int(success) == 1, algorithm=ALGORITHMS.get(int(algorithm), f"code {algorithm}"),
                           pictures=int(count), max_time_s=float(max_t), min_time_s=float(min_t),
                           overflow_percent=float(overflow), max_load_percent=float(load))

    def capture_luminance(self, exposure_s: float, window: Window | None = None) -> LuminanceImage:
        self._call("iSinglePic", float(exposure_s), self.smear, self.modulation_hz)
        return self._picture(window)

    def capture_hdr_luminance(self, max_exposure_s: float, min_exposure_s: float, factor: float,
                              window: Window | None = None) -> LuminanceImage:
        self._call("iHighDynPic", float(max_exposure_s), float(min_exposure_s), float(factor), self.smear,
                   self.modulation_hz)
        return self._picture(window)

    def _picture(self, window: Window | None) -> LuminanceImage:
        info = self.last_capture()
        if not info.success:
            raise DeviceError(self._name, f"iCaptureGetLastInfo reports the {info.algorithm} capture failed")
        window = self.full_window() if window is None else window
        return LuminanceImage(
            pixels_cd_m2=self.read_luminance(window), window=window, exposures_s=info.exposures_s(),
            algorithm=info.algorithm, overflow_fraction=info.overflow_percent / 100.0,
            peak_load=info.max_load_percent / 100.0, meta={"modulation_hz": self.modulation_hz, "smear": self.smear})

    def read_luminance(self, window: Window) -> np.ndarray:
        """The luminance image's pixels of `window` (float32 cd/m², rows top first)."""
        first_line, last_line, first_col, last_col, _dims = self._call("iImageGetSize", LUMINANCE_IMAGE)
        height, width = int(last_line) - int(first_line) + 1, int(last_col) - int(first_col) + 1
        if (width, height) != (self.sensor.width_px, self.sensor.height_px):
            raise DeviceError(self._name, f"the luminance image is {width}×{height} px, the rig file's camera "
                                          f"section says {self.sensor.width_px}×{self.sensor.height_px}")
        l0, c0 = int(first_line) + window.y0, int(first_col) + window.x0
        l1, c1 = l0 + window.height - 1, c0 + window.width - 1
        (dump,) = self._call("iImageGetDumpToMemory", LUMINANCE_IMAGE, l0, l1, c0, c1)
        data = np.frombuffer(bytes(dump), dtype="<f4")
        if data.size != window.height * window.width:
            raise DeviceError(self._name, f"iImageGetDumpToMemory({l0}, {l1}, {c0}, {c1}) gave {data.size} values, "
                                          f"expected {window.height} lines × {window.width} columns (ends included)")
        return data.reshape(window.height, window.width)

    def close(self) -> None:
        """`iClose(0)`: close LabSoft without asking to save."""
        answer = self._invoke("iClose", 0)
        code = answer if isinstance(answer, int) else answer[0]
        if code == CLOSE_REFUSED:
            raise DeviceError(self._name, "iClose: LabSoft refused to close")
        if code != 0:
            raise DeviceError(self._name, f"iClose returned error code {code}: {self._error_text(code)}")
