"""Assemble the built-in simulated rig: five simulated devices on one SimWorld."""

from __future__ import annotations

from typing import Mapping

from drivers.interfaces import RigDevices, TwoAxisPositioner
from rig.brdf_models import get_model
from rig.rigconfig import RigConfig
from simulators.camera import SimCamera
from simulators.devices import SimAxis, SimIlluminanceMeter, SimLampSupply
from simulators.world import SimWorld


def build_simulated_rig(config: RigConfig, brdf_model: str,
                        brdf_params: Mapping[str, float]) -> tuple[RigDevices, SimWorld]:
    """Devices plus the world behind them (tests compare against the world's truth)."""
    world = SimWorld(config, get_model(brdf_model), brdf_params)
    axes = {name: SimAxis(world, name, getattr(config.axes, name))
            for name in ("stage_vertical", "stage_normal", "arm_azimuth", "arm_polar")}
    devices = RigDevices(
        arm=TwoAxisPositioner("arm", axes["arm_azimuth"], axes["arm_polar"]),
        stage=TwoAxisPositioner("stage", axes["stage_vertical"], axes["stage_normal"]),
        lamp=SimLampSupply(world),
        meter=SimIlluminanceMeter(world),
        camera=SimCamera(world),
        clock=world.clock,
        simulated=True,
    )
    return devices, world
