"""Simulated worlds the camera tests share (importable from every test folder: `pythonpath = ["tests"]`)."""

from __future__ import annotations

from rig.config.rigfile import RigConfig
from rig.core.clock import Clock
from rig.physics.brdf_models import get_model
from rig.physics.geometry import AXIS_NAMES, inverse_deg
from rig.simulators.world import SimWorld


def lit_world(clock: Clock | None = None) -> SimWorld:
    """A Lambertian sample, lamp on, posed at (θi, φi, θo, φo) = (30, 0, 20, 90)°, so that frames show it."""
    world = SimWorld(RigConfig(), get_model("lambert"), {"kd": 0.5}, clock=clock)
    world.lamp.set_current(world.config.lamp.current_a, 0)
    world.lamp.switch(True)
    for name, value in zip(AXIS_NAMES, inverse_deg(30, 0, 20, 90).as_array()):
        world.axis_truth[name] = lambda value=float(value): value
    return world
