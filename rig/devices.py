"""Connect the five devices named in a rig configuration."""

from __future__ import annotations

import importlib
import inspect
from collections.abc import Callable
from pathlib import Path

from rig.config.files import clip
from rig.config.rigfile import (
    POSITIONER_AXES,
    SERVED_CAMERA,
    CameraConfig,
    CameraDevice,
    PositionerDevice,
    RigConfig,
    RigConfigError,
)
from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.drivers.delta_sm import DeltaSM
from rig.drivers.interfaces import LuminanceCamera, RigDevices, TwoAxisPositioner
from rig.drivers.modbus_axis import ModbusAxisController
from rig.drivers.p9710 import P9710
from rig.drivers.sim_camera import ServedCamera

__all__ = ["POSITIONER_AXES", "camera_class", "check_devices", "connect_devices", "vendor_camera"]


def _positioner(config: RigConfig, which: str, dev: PositionerDevice, clock: Clock) -> TwoAxisPositioner:
    controller = ModbusAxisController(dev.address, device_id=dev.device_id, name=which, clock=clock,
                                      timeout_s=dev.timeout_s)
    try:
        controller.identity()    # connect now: a wrong address should fail here, not at the first move
    except BaseException:
        controller.close()
        raise
    axes = []
    for index, axis_name in enumerate(POSITIONER_AXES[which]):
        cfg = getattr(config.axes, axis_name)
        axes.append(controller.axis(index, axis_name, dev.steps_per_degree, cfg.speed_deg_s,
                                    cfg.accel_deg_s2, cfg.settle_s))
    return TwoAxisPositioner(which, *axes)


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


def check_devices(config: RigConfig, source: str | Path = "<rig>") -> None:
    """What connecting to a hardware rig needs beyond the rig file's schema, checked before anything is
    opened or written: real addresses and a usable camera plug-in (the simulated rig picks its own
    addresses and brings its own camera). RigConfigError (bad input) naming `source` if not; `rig plan`
    needs neither."""
    if config.simulated:
        return
    try:
        _check_addresses(config)
        if config.devices.camera.driver != SERVED_CAMERA:
            camera_class(config.devices.camera, config.camera)
    except RigConfigError as exc:
        raise RigConfigError(f"{source}: {exc}") from None


def _check_addresses(config: RigConfig) -> None:
    for name in ("arm", "stage", "lamp", "meter"):
        if getattr(config.devices, name).address == "auto":
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
            camera = ServedCamera(d.camera.options["address"], clock=clock)
            opened.append(camera)
        arm = _positioner(config, "arm", d.arm, clock)
        opened.append(arm)
        stage = _positioner(config, "stage", d.stage, clock)
        opened.append(stage)
        lamp = DeltaSM(d.lamp.address, clock=clock, timeout_s=d.lamp.timeout_s, current_a=config.lamp.current_a,
                       current_limit_a=config.lamp.current_limit_a, watchdog_s=config.lamp.watchdog_s,
                       ramp_s=config.lamp.ramp_s)
        opened.append(lamp)
        meter = P9710(d.meter.address, calibration_lx_per_a=config.meter.calibration_lx_per_a, clock=clock,
                      timeout_s=d.meter.timeout_s, integration_s=config.meter.integration_s,
                      autorange_s=config.meter.autorange_s)
        opened.append(meter)
        if camera is None:
            camera = vendor_camera(config, d.camera)
        return RigDevices(arm=arm, stage=stage, lamp=lamp, meter=meter, camera=camera, clock=clock,
                          simulated=config.simulated)
    except BaseException:
        for dev in reversed(opened):
            try:
                dev.close()
            except Exception:  # already failing: report the original error
                pass
        raise
