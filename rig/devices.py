"""Connect the five devices named in a rig configuration, each through its registered driver.

Every device entry names a driver installed in the entry-point group `rig.drivers`
(rig.drivers.registry), rig's own included, and is built by the driver's
`from_rig(*, clock, settings, **options)`: `settings` is the rig file's section for
its role, the options are the entry's typed keys (rig's own drivers) or its own keys
(a plug-in). A `python:package.module:Class` camera is the older plug-in form.
"""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Callable
from pathlib import Path
from typing import Any

from rig.config.files import clip
from rig.config.rigdevices import POSITIONER_AXES, SERVED_CAMERA, CameraDevice, DeviceEntry
from rig.config.rigfile import CameraConfig, RigConfig, RigConfigError
from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.drivers.interfaces import CalibratedLuminanceCamera, LuminanceCamera, RigDevices
from rig.drivers.registry import driver_class

__all__ = ["POSITIONER_AXES", "camera_class", "check_devices", "connect_devices", "vendor_camera"]


#: The role of each device entry (rig.drivers.registry.ROLES).
ROLE_OF = {"arm": "positioner", "stage": "positioner", "lamp": "lamp", "meter": "meter", "camera": "camera",
           "attenuator": "attenuator"}


def _settings(config: RigConfig, which: str) -> Any:
    """The rig-file section a driver's `from_rig` gets: its role's section; a positioner's two axes by name."""
    if ROLE_OF[which] == "positioner":
        return {axis: getattr(config.axes, axis) for axis in POSITIONER_AXES[which]}
    return getattr(config, which)


def _registered(which: str, entry: DeviceEntry) -> Callable[..., Any]:
    """The registered driver's `from_rig` for a device entry, with the entry's options bound to it checked;
    RigConfigError (bad input) naming the key if it is not installed or does not take them."""
    key = f"key 'devices.{which}.driver'"
    try:
        cls = driver_class(ROLE_OF[which], entry.driver)
    except LookupError as exc:
        raise RigConfigError(f"{key}: {exc}") from None
    fixed = {"clock": None, "settings": None, **({"name": which} if ROLE_OF[which] == "positioner" else {})}
    options = entry.driver_options()
    try:
        inspect.signature(cls.from_rig).bind(**fixed, **options)
    except TypeError as exc:
        raise RigConfigError(f"{key}: driver {entry.driver!r} does not take the options "
                             f"{', '.join(options) or '(none)'}: {clip(str(exc), 200)}") from None
    build: Callable[..., Any] = cls.from_rig
    return build


def _connect(config: RigConfig, which: str, clock: Clock) -> Any:
    """Build and connect one device through its registered driver; a failure that is not the driver's own
    DeviceError (a vendor SDK's exception) becomes one naming the device."""
    entry = getattr(config.devices, which)
    try:
        build = _registered(which, entry)
    except RigConfigError as exc:
        raise DeviceError(which, str(exc)) from None
    extra = {"name": which} if ROLE_OF[which] == "positioner" else {}
    try:
        return build(clock=clock, settings=_settings(config, which), **extra, **entry.driver_options())
    except DeviceError:
        raise
    except Exception as exc:        # the plug-in's own exceptions: the device did not start
        raise DeviceError(which, f"driver {entry.driver!r} failed to start: {type(exc).__name__}: "
                                 f"{clip(str(exc), 200)}") from None


def camera_class(dev: CameraDevice, camera: CameraConfig) -> type[LuminanceCamera]:
    """The class named by `devices.camera.driver` (`python:package.module:Class`), checked to be one
    rig can use: an importable, concrete LuminanceCamera whose constructor takes (camera config,
    **options) with the rig file's options. RigConfigError (bad input) naming the key otherwise."""
    where = f"key 'devices.camera.driver': {dev.driver!r}"
    if dev.driver == "simulated":
        raise RigConfigError("key 'devices.camera.driver': the simulated camera exists only on the simulated rig")
    module_name, class_name = dev.driver.removeprefix("python:").split(":")
    try:
        cls = getattr(importlib.import_module(module_name), class_name)
    except Exception as exc:        # ImportError, AttributeError, or whatever the module raises on import
        raise RigConfigError(f"key 'devices.camera.driver': cannot load camera driver {dev.driver!r}: "
                             f"{type(exc).__name__}: {clip(str(exc), 200)}") from None
    if not (inspect.isclass(cls) and issubclass(cls, LuminanceCamera)):
        raise RigConfigError(f"{where} is not a class implementing rig.drivers.interfaces.LuminanceCamera")
    if inspect.isabstract(cls):
        missing = ", ".join(sorted(cls.__abstractmethods__))
        raise RigConfigError(f"{where} does not implement {missing}")
    try:
        inspect.signature(cls).bind(camera, **dev.options)
    except (TypeError, ValueError) as exc:
        raise RigConfigError(f"{where}: its constructor does not take (camera_config, **options) with the options "
                             f"{', '.join(dev.options) or '(none)'} of the rig file: {clip(str(exc), 200)}") from None
    return cls


def check_devices(config: RigConfig, source: str | Path = "<rig>") -> list[str]:
    """What connecting to a hardware rig needs beyond the rig file's schema, checked before anything is
    opened or written: real addresses and, for every device, an installed driver whose class imports and
    takes the entry's options (a camera plug-in's class checked as such); the simulated rig picks its own
    addresses and brings its own devices. RigConfigError (bad input) naming `source` if not; `rig plan`
    needs neither. What was checked, one line per device (`rig devices --check` prints them)."""
    if config.simulated:
        return []
    checked = []
    try:
        _check_addresses(config)
        for which in ROLE_OF:
            entry = getattr(config.devices, which)
            if entry is None:                   # an optional device the rig does not have
                continue
            if which == "camera" and entry.driver.startswith("python:"):
                cls: Any = camera_class(entry, config.camera)
            elif entry.driver != "simulated":
                cls = _registered(which, entry)
            else:
                camera_class(entry, config.camera)      # says the simulated camera needs the simulated rig
            if which == "camera" and config.camera.calibration_file and _calibrates_itself(cls):
                raise RigConfigError(f"key 'camera.calibration_file': camera driver {entry.driver!r} delivers "
                                     "calibrated luminance (its own calibration); a calibration file is for a raw "
                                     "camera (docs/camera-calibration.md)")
            checked.append(_described(which, entry, cls))
    except RigConfigError as exc:
        raise RigConfigError(f"{source}: {exc}") from None
    return checked


def _described(which: str, entry: DeviceEntry, build: Any) -> str:
    """One device as `check_devices` found it: driver, the class it imports, where it would connect."""
    cls = getattr(build, "__self__", build)
    options = entry.driver_options()
    shown: dict[str, Any]
    if entry.driver == entry.BUILTIN:       # rig's own driver: where it connects, and a positioner's drives
        shown = {key: options[key] for key in ("address", "map", "device_ids") if key in options}
    else:                                   # a plug-in's own keys, as the rig file gives them
        shown = options
    where = [f"{key} {clip(str(value), 80)}" for key, value in shown.items()]
    return (f"{which:10s} driver {entry.driver} → {cls.__module__}.{cls.__qualname__}"
            + "".join(f"; {part}" for part in where))


def _calibrates_itself(build: Any) -> bool:
    """Whether a camera driver (its class, or its class's `from_rig`) is a CalibratedLuminanceCamera."""
    cls = getattr(build, "__self__", build)
    return inspect.isclass(cls) and issubclass(cls, CalibratedLuminanceCamera)


def _check_addresses(config: RigConfig) -> None:
    for name in ("arm", "stage", "lamp", "meter", "attenuator"):
        entry = getattr(config.devices, name)
        if entry is not None and entry.driver == entry.BUILTIN and entry.address == "auto":
            raise RigConfigError(f"key 'devices.{name}.address': address 'auto' only works on the simulated rig; "
                                 "give the device's address")


def vendor_camera(config: RigConfig, dev: CameraDevice) -> LuminanceCamera:
    """Build the vendor camera with the camera section and options; any failure is a DeviceError."""
    try:
        cls = camera_class(dev, config.camera)
    except RigConfigError as exc:
        raise DeviceError("camera", str(exc)) from None
    build: Callable[..., LuminanceCamera] = cls      # the plug-in's constructor, checked by camera_class
    try:
        return build(config.camera, **dev.options)
    except DeviceError:
        raise
    except Exception as exc:        # the vendor SDK's own exceptions: the camera did not start
        raise DeviceError("camera", f"camera driver {dev.driver!r} failed to start: "
                                    f"{type(exc).__name__}: {clip(str(exc), 200)}") from None


def connect_camera(config: RigConfig, clock: Clock) -> LuminanceCamera:
    """The rig's camera alone (`rig calibrate camera` needs nothing else): its registered driver, or a
    `python:` vendor class."""
    dev = config.devices.camera
    return vendor_camera(config, dev) if dev.driver.startswith("python:") else _connect(config, "camera", clock)


def connect_devices(config: RigConfig, clock: Clock, camera: LuminanceCamera | None = None) -> RigDevices:
    """Open every device; on any failure close what was opened and re-raise.

    RigConfigError (bad input) before anything is opened if an address is `auto`; DeviceError if a
    device does not answer as it should or the camera plug-in cannot be built."""
    _check_addresses(config)
    d = config.devices
    opened: list = []
    try:
        if camera is None and d.camera.driver == SERVED_CAMERA:
            # First: the served rig's camera session is what refuses a second client, before any other
            # device of the rig has been touched.
            camera = _connect(config, "camera", clock)
            opened.append(camera)
        arm = _connect(config, "arm", clock)
        opened.append(arm)
        stage = _connect(config, "stage", clock)
        opened.append(stage)
        lamp = _connect(config, "lamp", clock)
        opened.append(lamp)
        meter = _connect(config, "meter", clock)
        opened.append(meter)
        attenuator = None if d.attenuator is None else _connect(config, "attenuator", clock)
        if attenuator is not None:
            opened.append(attenuator)
        if camera is None:
            camera = connect_camera(config, clock)
        return RigDevices(arm=arm, stage=stage, lamp=lamp, meter=meter, camera=camera, clock=clock,
                          simulated=config.simulated, attenuator=attenuator)
    except BaseException:
        for dev in reversed(opened):
            try:
                dev.close()
            except Exception:  # already failing: report the original error
                pass
        raise
