"""Connect the five devices named in a rig configuration."""

from __future__ import annotations

import importlib

from drivers.delta_sm import DeltaSM
from drivers.interfaces import Clock, DeviceError, LuminanceCamera, RigDevices, TwoAxisPositioner
from drivers.modbus_axis import ModbusAxisController
from drivers.p9710 import P9710
from rig.rigconfig import CameraDevice, PositionerDevice, RigConfig

#: Axis names of each positioner, in controller axis order.
POSITIONER_AXES = {"arm": ("arm_azimuth", "arm_polar"), "stage": ("stage_vertical", "stage_normal")}


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


def vendor_camera(config: RigConfig, dev: CameraDevice) -> LuminanceCamera:
    """Import `python:package.module:Class` and build it with the camera section and options."""
    module_name, class_name = dev.driver.removeprefix("python:").split(":")
    try:
        cls = getattr(importlib.import_module(module_name), class_name)
    except (ImportError, AttributeError) as exc:
        raise DeviceError("camera", f"cannot load camera driver {dev.driver!r}: {exc}") from None
    return cls(config.camera, **dev.options)


def connect_devices(config: RigConfig, clock: Clock, camera: LuminanceCamera | None = None) -> RigDevices:
    """Open every device; on any failure close what was opened and re-raise."""
    d = config.devices
    for name in ("arm", "stage", "lamp", "meter"):
        if getattr(d, name).address == "auto":
            raise DeviceError(name, "address 'auto' only works on the simulated rig; give the device's address")
    opened: list = []
    try:
        arm = _positioner(config, "arm", d.arm, clock)
        opened.append(arm)
        stage = _positioner(config, "stage", d.stage, clock)
        opened.append(stage)
        lamp = DeltaSM(d.lamp.address, clock=clock, timeout_s=d.lamp.timeout_s)
        opened.append(lamp)
        meter = P9710(d.meter.address, calibration_lx_per_a=config.meter.calibration_lx_per_a, clock=clock,
                      timeout_s=d.meter.timeout_s, integration_s=config.meter.integration_s)
        opened.append(meter)
        if camera is None:
            if d.camera.driver == "simulated":
                raise DeviceError("camera", "the simulated camera exists only on the simulated rig")
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
