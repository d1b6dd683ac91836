"""Open the rig a command runs on: the simulated rig (protocol peers in-process) or real devices."""

from __future__ import annotations

from contextlib import contextmanager
from typing import Iterator, Mapping

from drivers.factory import connect_devices
from drivers.interfaces import RigDevices
from drivers.wallclock import WallClock
from rig.rigconfig import RigConfig

#: BRDF of the simulated sample when a command (e.g. `rig devices`) has no campaign.
NEUTRAL_SAMPLE = ("lambert", {"kd": 0.5})


@contextmanager
def open_rig(config: RigConfig, brdf_model: str | None = None,
             brdf_params: Mapping[str, float] | None = None) -> Iterator[RigDevices]:
    """Connected devices for the duration of the block; everything is closed afterwards."""
    if config.simulated:
        from simulators.rig import (
            SimulatedRig,  # only the simulated rig needs the simulators
        )

        model, params = (brdf_model, brdf_params) if brdf_model else NEUTRAL_SAMPLE
        with SimulatedRig(config, model, params) as sim:
            yield sim.devices
        return
    devices = connect_devices(config, WallClock())
    try:
        yield devices
    finally:
        devices.close()
