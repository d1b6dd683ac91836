"""GenICam machine-vision camera through Basler's pypylon, as a raw-frame LuminanceCamera.

Most home-built imaging goniophotometers use a machine-vision camera. pypylon (the
Basler pylon runtime ships in its wheel) speaks GenICam to any USB3 Vision or GigE
Vision camera, and its camera emulation (`PYLON_CAMEMU=1`) is a real GenICam device
for tests. The features rig sets are the SFNC names (ExposureTime in µs, Gain,
BlackLevel, PixelFormat, Width/Height/OffsetX/OffsetY), with the older Basler names
(ExposureTimeAbs, GainRaw, BlackLevelRaw) where a camera has only those.

Only the numbers a camera itself knows come from it: the sensor size, the bit depth
of the pixel format, the exposure range. The radiometry (gain K, read noise, black
level, calibration) is the rig file's camera section, which must agree with the
camera on size and bit depth: its DN are this pixel format's DN. A camera has no
shutter, so dark frames are refused unless the rig is made dark another way
(option `dark_frames`, docs/genicam.md). pypylon is imported when a camera is
opened, so this module imports everywhere.
"""

from __future__ import annotations

import importlib
import math
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from rig.core.errors import DeviceError
from rig.core.values import Frame, SensorInfo, Window
from rig.drivers.interfaces import LuminanceCamera

#: Monochrome pixel formats rig reads (unpacked, one uint8/uint16 per pixel) and their bit depths.
MONO_BITS = {"Mono8": 8, "Mono10": 10, "Mono12": 12, "Mono14": 14, "Mono16": 16}
#: What `capture_dark` does: refuse (no shutter), or take an ordinary frame the operator keeps dark.
DARK_FRAMES = ("refuse", "same")
#: Feature names by what they set: the SFNC name first, then the older Basler one.
EXPOSURE_US = ("ExposureTime", "ExposureTimeAbs")
GAIN = ("Gain", "GainRaw")
BLACK_LEVEL = ("BlackLevel", "BlackLevelRaw")


class CameraSection(Protocol):
    """What the driver reads of the rig file's camera section (rig.config.rigfile.CameraConfig)."""

    def sensor_info(self) -> SensorInfo: ...


def load_pylon() -> Any:
    """`pypylon.pylon`, or a DeviceError saying how to install it."""
    try:
        return importlib.import_module("pypylon.pylon")
    except ImportError as exc:
        raise DeviceError("camera", f"the GenICam driver needs pypylon: pip install 'rig[genicam]' ({exc})") from None


@dataclass(frozen=True)
class RoiSteps:
    """The camera's region-of-interest grid: sensor size, smallest width/height, and increments."""

    width_px: int
    height_px: int
    min_width: int
    min_height: int
    width_inc: int
    height_inc: int
    x_inc: int
    y_inc: int

    def fit(self, window: Window) -> Window:
        """The smallest window on the grid that contains `window` (itself when it is on the grid)."""
        if not (window.x0 >= 0 and window.y0 >= 0 and window.width > 0 and window.height > 0
                and window.x0 + window.width <= self.width_px and window.y0 + window.height <= self.height_px):
            raise ValueError(f"window {window} is not inside the {self.width_px}×{self.height_px} sensor")
        x0, width = _fit_span(window.x0, window.width, self.x_inc, self.min_width, self.width_inc, self.width_px)
        y0, height = _fit_span(window.y0, window.height, self.y_inc, self.min_height, self.height_inc,
                               self.height_px)
        return Window(x0, y0, width, height)


def _fit_span(start: int, length: int, start_inc: int, min_length: int, length_inc: int, size: int) -> tuple[int, int]:
    """Offset and length on the grid covering [start, start + length): the offset rounded down, the length
    rounded up from its minimum; moved back by offset steps if it then runs past the sensor's end."""
    first = start - start % start_inc
    span = max(start + length - first, min_length)
    span = min_length + math.ceil((span - min_length) / length_inc) * length_inc
    while first + span > size and first >= start_inc:
        first -= start_inc
    if first + span > size:
        raise ValueError(f"no region on the camera's grid covers pixels {start}…{start + length - 1}")
    return first, span


class GenICamCamera(LuminanceCamera):
    """A GenICam camera through pypylon: a rig camera plug-in, `python:rig.drivers.genicam:GenICamCamera`.

    Options: `serial` (empty: the first camera found); `pixel_format` (a Mono format, "auto": the one of
    the rig file's bit depth); `gain` (the Gain feature's value, fixed; GainAuto off); `black_level`
    (BlackLevel; None leaves it as the camera has it); `grab_timeout_s` (time allowed for a frame beyond
    its exposure); `dark_frames` ("refuse" or "same", see DARK_FRAMES).
    """

    def __init__(self, camera_config: CameraSection, *, serial: str = "", pixel_format: str = "auto",
                 gain: float = 0.0, black_level: float | None = None, grab_timeout_s: float = 5.0,
                 dark_frames: str = "refuse"):
        if dark_frames not in DARK_FRAMES:
            raise DeviceError("camera", f"GenICam option dark_frames is {dark_frames!r}: use one of {DARK_FRAMES}")
        if not grab_timeout_s > 0:
            raise DeviceError("camera", f"GenICam option grab_timeout_s must be > 0 s, not {grab_timeout_s!r}")
        self.grab_timeout_s = float(grab_timeout_s)
        self.dark_frames = dark_frames
        self.pylon = load_pylon()
        self._name = f"camera {serial}" if serial else "camera"
        self.camera = self._open(str(serial))
        try:
            self._configure(camera_config, pixel_format, float(gain), black_level)
        except BaseException:
            self.close()
            raise

    # -- pylon calls ----------------------------------------------------------------------------
    @contextmanager
    def _calls(self, what: str) -> Iterator[None]:
        """Turn pylon's exceptions into a DeviceError naming `what` failed; a timeout is transient."""
        try:
            yield
        except self.pylon.TimeoutException as exc:
            raise DeviceError(self._name, f"{what} timed out: {_text(exc)}", transient=True) from None
        except self.pylon.GenericException as exc:
            raise DeviceError(self._name, f"{what} failed: {_text(exc)}") from None

    def _open(self, serial: str) -> Any:
        factory = self.pylon.TlFactory.GetInstance()
        with self._calls("listing the cameras"):
            found = list(factory.EnumerateDevices())
        infos = [d for d in found if not serial or d.GetSerialNumber() == serial]
        if not infos:
            seen = ", ".join(f"{d.GetModelName()} {d.GetSerialNumber()}" for d in found) or "none"
            raise DeviceError(self._name, f"no GenICam camera{' with serial ' + repr(serial) if serial else ''} "
                                          f"found (cameras seen: {seen})")
        info = infos[0]
        self._name = f"camera {info.GetVendorName()} {info.GetModelName()} {info.GetSerialNumber()}"
        with self._calls("opening"):
            camera = self.pylon.InstantCamera(factory.CreateDevice(info))
            camera.Open()
        return camera

    def _feature(self, names: tuple[str, ...]) -> Any:
        """The first of `names` the camera has, or None."""
        for name in names:
            node = getattr(self.camera, name)
            if node.IsReadable():
                return node
        return None

    def _set(self, names: tuple[str, ...], value: Any) -> Any:
        """Set the first feature of `names` the camera has; its value read back."""
        node = self._feature(names)
        if node is None:
            raise DeviceError(self._name, f"has none of the features {', '.join(names)}")
        with self._calls(f"setting {names[0]} to {value}"):
            node.Value = value
            return node.Value

    def _configure(self, camera_config: CameraSection, pixel_format: str, gain: float,
                   black_level: float | None) -> None:
        """Free-running single frames at fixed gain and exposure, in the chosen format, full sensor."""
        sensor = camera_config.sensor_info()
        self.pixel_format = self._choose_format(pixel_format, sensor.bit_depth)
        for auto in ("ExposureAuto", "GainAuto", "BlackLevelAuto"):
            if getattr(self.camera, auto).IsWritable():
                self._set((auto,), "Off")
        if self.camera.TriggerSelector.IsWritable() and "FrameStart" in self.camera.TriggerSelector.Symbolics:
            self._set(("TriggerSelector",), "FrameStart")     # free-running: each frame starts on its own
        if self.camera.TriggerMode.IsWritable():
            self._set(("TriggerMode",), "Off")
        self.pixel_format = self._set(("PixelFormat",), self.pixel_format)
        self.gain = float(self._set(GAIN, gain))
        self.black_level = None if black_level is None else float(self._set(BLACK_LEVEL, black_level))
        self.roi = self._roi_steps()
        if (self.roi.width_px, self.roi.height_px) != (sensor.width_px, sensor.height_px):
            raise DeviceError(self._name, f"the sensor is {self.roi.width_px}×{self.roi.height_px} px, the rig "
                                          f"file's camera section says {sensor.width_px}×{sensor.height_px}")
        exposure = self._feature(EXPOSURE_US)
        if exposure is None:
            raise DeviceError(self._name, f"has none of the features {', '.join(EXPOSURE_US)}")
        with self._calls("reading the exposure range"):
            self._exposure_us = (float(exposure.Min), float(exposure.Max),
                                 float(exposure.Inc) if exposure.HasInc() else 0.0)
        self.sensor = replace(sensor, min_exposure_s=max(sensor.min_exposure_s, self._exposure_us[0] * 1e-6),
                              max_exposure_s=min(sensor.max_exposure_s, self._exposure_us[1] * 1e-6))
        self._window: Window | None = None

    def _choose_format(self, requested: str, bit_depth: int) -> str:
        """`requested` (or, "auto", the Mono format of the rig file's bit depth), checked to be offered and of
        that bit depth: the rig file's gain K and black level are DN of that depth."""
        with self._calls("reading the pixel formats"):
            offered = [name for name in self.camera.PixelFormat.Symbolics if name in MONO_BITS]
        wanted = f"Mono{bit_depth}" if requested == "auto" else requested
        if wanted not in offered:
            raise DeviceError(self._name, f"pixel format {wanted!r} is not offered; the camera's monochrome "
                                          f"formats: {', '.join(offered) or 'none'}")
        if MONO_BITS[wanted] != bit_depth:
            raise DeviceError(self._name, f"pixel format {wanted} gives {MONO_BITS[wanted]}-bit DN, the rig file's "
                                          f"camera section says bit_depth {bit_depth}: make the two agree")
        return wanted

    def _roi_steps(self) -> RoiSteps:
        with self._calls("reading the region-of-interest grid"):
            cam = self.camera
            cam.OffsetX.Value = 0              # the widest a region can be depends on its offset
            cam.OffsetY.Value = 0
            full_w = self._feature(("WidthMax",))
            full_h = self._feature(("HeightMax",))
            return RoiSteps(
                width_px=int(full_w.Value if full_w is not None else cam.Width.Max),
                height_px=int(full_h.Value if full_h is not None else cam.Height.Max),
                min_width=int(cam.Width.Min), min_height=int(cam.Height.Min),
                width_inc=int(cam.Width.Inc), height_inc=int(cam.Height.Inc),
                x_inc=int(cam.OffsetX.Inc), y_inc=int(cam.OffsetY.Inc))

    # -- the camera -----------------------------------------------------------------------------
    @classmethod
    def from_rig(cls, *, clock: Any, settings: CameraSection, **options: Any) -> GenICamCamera:
        """The rig-file contract (rig.drivers.registry): `settings` is the rig file's `camera` section; a grab
        blocks for the exposure, so no clock is needed."""
        return cls(settings, **options)

    def identity(self) -> str:
        return f"GenICam {self._name.removeprefix('camera ')} ({self.pixel_format})"

    def set_window(self, window: Window) -> Window:
        """Read `window` from now on, grown to the camera's grid; the region set."""
        try:
            region = self.roi.fit(window)
        except ValueError as exc:
            raise DeviceError(self._name, str(exc)) from None
        if region != self._window:
            with self._calls(f"setting the region {region}"):
                cam = self.camera
                cam.OffsetX.Value = 0          # shrink the offsets first, so every width/height is allowed
                cam.OffsetY.Value = 0
                cam.Width.Value = region.width
                cam.Height.Value = region.height
                cam.OffsetX.Value = region.x0
                cam.OffsetY.Value = region.y0
            self._window = region
        return region

    def set_exposure(self, exposure_s: float) -> float:
        """Set the exposure time, clipped to the camera's range and on its step; the time realised (s)."""
        if not (math.isfinite(exposure_s) and exposure_s > 0):
            raise DeviceError(self._name, f"exposure time {exposure_s!r} s is not a positive number")
        low, high, step = self._exposure_us
        wished = float(np.clip(exposure_s * 1e6, low, high))
        if step > 0:
            wished = min(low + round((wished - low) / step) * step, high)
        return float(self._set(EXPOSURE_US, wished)) * 1e-6

    def capture(self, exposure_s: float, window: Window | None = None) -> Frame:
        return self._grab(exposure_s, window, dark=False)

    def capture_dark(self, exposure_s: float, window: Window | None = None) -> Frame:
        """A camera has no shutter: refused, or (dark_frames "same") an ordinary frame the operator keeps dark."""
        if self.dark_frames == "refuse":
            raise DeviceError(self._name, "a GenICam camera has no shutter, so rig cannot take dark frames; "
                                          "cap the lens and set the option dark_frames: same (docs/genicam.md)")
        return self._grab(exposure_s, window, dark=True)

    def _grab(self, exposure_s: float, window: Window | None, dark: bool) -> Frame:
        window = self.full_window() if window is None else window
        region = self.set_window(window)
        realised_s = self.set_exposure(exposure_s)
        timeout_ms = math.ceil((realised_s + self.grab_timeout_s) * 1000)
        with self._calls(f"grabbing a {realised_s:g} s frame of {region}"):
            result = self.camera.GrabOne(timeout_ms)
            try:
                if not result.GrabSucceeded():
                    raise DeviceError(self._name, f"grab of a {realised_s:g} s frame failed: error "
                                                  f"{result.GetErrorCode():#x} {result.GetErrorDescription()}",
                                      transient=True)
                pixels = np.array(result.Array, dtype=np.uint16)     # a copy: the buffer goes back to pylon
            finally:
                result.Release()
        if pixels.shape != (region.height, region.width):
            raise DeviceError(self._name, f"delivered a {pixels.shape} image for the region {region}")
        return Frame(pixels_dn=pixels[region.inner(window)], exposure_s=realised_s, window=window, dark=dark,
                     meta={"pixel_format": self.pixel_format, "gain": self.gain, "black_level": self.black_level,
                           "region": region})

    def close(self) -> None:
        """Close the camera and release the device; safe to call twice."""
        with self._calls("closing"):
            self.camera.Close()
            self.camera.DestroyDevice()


def _text(exc: BaseException) -> str:
    """pylon's message without its source-file suffix (": XException thrown in … (file 'x.h', line 81)")."""
    text = str(exc).strip()
    return text.split(" : ")[0] if " : " in text else text
