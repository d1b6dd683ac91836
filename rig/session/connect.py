"""Open the rig a command runs on: the simulated rig (protocol peers in-process) or real devices."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from contextlib import AbstractContextManager, contextmanager

from rig.config.campaign import Campaign
from rig.config.rigfile import RigConfig
from rig.devices import connect_devices
from rig.drivers.interfaces import RigDevices
from rig.drivers.wallclock import WallClock

#: BRDF of the simulated sample when a command (e.g. `rig devices`) has no campaign.
NEUTRAL_SAMPLE = ("lambert", {"kd": 0.5})


@contextmanager
def open_rig(config: RigConfig, brdf_model: str | None = None,
             brdf_params: Mapping[str, float] | None = None) -> Iterator[RigDevices]:
    """Connected devices for the duration of the block; everything is closed afterwards."""
    close: Callable[[], None]
    if config.simulated:
        from rig.simulators.rig import SimulatedRig  # only the simulated rig needs the simulators

        model, params = (brdf_model, brdf_params) if brdf_model and brdf_params is not None else NEUTRAL_SAMPLE
        sim = SimulatedRig(config, model, params)
        devices, close = sim.start(), sim.stop
    else:
        devices = connect_devices(config, WallClock(config.time_scale))
        close = devices.close
    try:
        yield devices
    finally:
        close()


def open_campaign_rig(campaign: Campaign, config: RigConfig) -> AbstractContextManager[RigDevices]:
    """`open_rig` for a campaign: on the simulated rig, its sample has the campaign's simulated BRDF."""
    truth = campaign.sample.simulated_brdf
    return open_rig(config, truth.model if truth else None, truth.params if truth else None)
