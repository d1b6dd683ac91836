"""The built-in simulated rig: protocol peers on loopback and the real drivers connected to them.

Two pairs of axis drives (arm, stage: Oriental Motor AZ drives on Modbus, or a Zaber ASCII daisy chain each, as the
rig file's driver names say), a SCPI lamp supply on TCP and a P9710 optometer on a
pseudo-terminal, all driving one SimWorld on one SimClock; the camera, which has no
public wire protocol, is the in-process SimCamera. The application sees exactly the
drivers it would use on hardware.
"""

from __future__ import annotations

from collections.abc import Mapping

from rig.config.rigdevices import DeviceEntry
from rig.config.rigfile import RigConfig, RigConfigError
from rig.devices import POSITIONER_AXES, connect_devices
from rig.drivers.interfaces import RigDevices
from rig.physics.brdf_models import get_model
from rig.simulators.camera import SimCamera
from rig.simulators.delta_sm_peer import DeltaSMPeer
from rig.simulators.fw102c_peer import FW102CPeer
from rig.simulators.oriental_az_peer import OrientalAZPeer
from rig.simulators.p9710_peer import P9710Peer
from rig.simulators.world import SimWorld
from rig.simulators.zaber_peer import ZaberPeer

Peer = OrientalAZPeer | ZaberPeer | DeltaSMPeer | P9710Peer | FW102CPeer
#: A Zaber positioner's (device, axis) addresses when its rig-file entry gives none (the driver's default).
ZABER_AXES = ((1, 1), (2, 1))
#: The drive map the simulated Modbus drives (OrientalAZPeer) answer.
SIMULATED_DRIVE_MAP = "oriental-az"


def _positioner_peer(world: SimWorld, name: str) -> OrientalAZPeer | ZaberPeer:
    """The peer of the arm's or the stage's controller, for the driver its rig-file entry names."""
    config = world.config
    entry = getattr(config.devices, name)
    axes = POSITIONER_AXES[name]
    if entry.driver == "zaber":
        addresses = entry.options.get("axes", ZABER_AXES)
        return ZaberPeer(world, [(device, number, axis, getattr(config.axes, axis))
                                 for (device, number), axis in zip(addresses, axes, strict=True)])
    if entry.driver != entry.BUILTIN:
        raise RigConfigError(f"key 'devices.{name}.driver': the simulated rig has peers for modbus-drive and zaber "
                             f"positioners, not {entry.driver!r}")
    if entry.map != SIMULATED_DRIVE_MAP:
        raise RigConfigError(f"key 'devices.{name}.map': the simulated rig's Modbus drives are Oriental Motor AZ "
                             f"drives (map {SIMULATED_DRIVE_MAP}), not {entry.map!r}")
    # on Modbus/TCP, as a lab's AZ drives are reached through a gateway to their RS-485 bus
    return OrientalAZPeer(world, [(axis, getattr(config.axes, axis)) for axis in axes], device_ids=entry.device_ids,
                          steps_per_degree=entry.steps_per_degree, gateway=True)


def _attenuator_peer(world: SimWorld) -> FW102CPeer:
    """The filter wheel's peer; the camera sees through the filter at its position."""
    entry = world.config.devices.attenuator
    assert entry is not None and world.config.attenuator is not None
    if entry.driver != entry.BUILTIN:
        raise RigConfigError(f"key 'devices.attenuator.driver': the simulated rig has a peer for {entry.BUILTIN} "
                             f"filter wheels, not {entry.driver!r}")
    wheel = FW102CPeer(world, positions=6 if max(f.position for f in world.config.attenuator.filters) <= 6 else 12)
    world.filter_position = lambda: wheel.position
    return wheel


def protocol_peers(world: SimWorld) -> dict[str, Peer]:
    """The peers of the rig's wire-protocol devices (arm, stage, lamp, meter, and the filter wheel if the rig
    has one), not yet started."""
    peers: dict[str, Peer] = {name: _positioner_peer(world, name) for name in POSITIONER_AXES}
    peers["lamp"] = DeltaSMPeer(world)
    peers["meter"] = P9710Peer(world)
    if world.config.devices.attenuator is not None:
        peers["attenuator"] = _attenuator_peer(world)
    return peers


def _addressed(entry: DeviceEntry, address: str) -> DeviceEntry:
    """The device entry with the peer's address: a typed key of rig's own driver, else a plug-in option."""
    if entry.driver == entry.BUILTIN:
        return entry.model_copy(update={"address": address})
    return entry.model_copy(update={"options": {**entry.options, "address": address}})


class SimulatedRig:
    """Context manager: `with SimulatedRig(cfg, "retrophong", params) as sim: sim.devices ...`.

    `sim.world` is the truth (for tests), `sim.peers` the protocol peers (for fault injection).
    """

    def __init__(self, config: RigConfig, brdf_model: str, brdf_params: Mapping[str, float]):
        self.config = config
        self.world = SimWorld(config, get_model(brdf_model), brdf_params)
        self.peers = protocol_peers(self.world)
        self.devices: RigDevices | None = None

    def start(self) -> RigDevices:
        try:
            addresses = {name: peer.start() for name, peer in self.peers.items()}
            d = self.config.devices
            wired = d.model_copy(update={name: _addressed(getattr(d, name), address)
                                         for name, address in addresses.items()})
            config = self.config.model_copy(update={"devices": wired})
            self.devices = connect_devices(config, self.world.clock, camera=SimCamera(self.world))
        except BaseException:
            self.stop()
            raise
        return self.devices

    def stop(self) -> None:
        if self.devices is not None:
            self.devices.close()
            self.devices = None
        for peer in self.peers.values():
            peer.stop()

    def __enter__(self) -> SimulatedRig:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()
