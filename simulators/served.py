"""The simulated rig as a standalone instrument server (`rig sim serve`).

The peers of the in-process simulated rig — two Modbus axis controllers and the
SM15K lamp supply on loopback TCP, the P-9710 meter on a pseudo-terminal — plus
the simulated camera behind docs/sim-camera-protocol.md, all driving one world
that lives in this process: axis positions, lamp temperature and age, the supply's
watchdog persist across client connections, as a real rig's do. The world runs on
a wall clock `speed` times faster than wall time, which stands still while a frame
renders (ServedClock: rendering is no rig time); the rig file written for clients
says `simulated: false` (they treat it as hardware) and carries the same
`time_scale`, so their waits shrink alike.

One client at a time: the camera session refuses a second one (rig connects the
camera first, so a second `rig run` or `rig devices` fails before touching any
other device), the lamp supply accepts one connection, and the meter's serial
port is opened with an exclusive lock.
"""

from __future__ import annotations

import os
import stat
import tempfile
from collections.abc import Mapping
from pathlib import Path

import yaml

from rig.config.rigdevices import SERVED_CAMERA
from rig.config.rigfile import RigConfig
from rig.physics.brdf_models import get_model
from rig.simulators.camera_server import CameraServer
from rig.simulators.clock import ServedClock
from rig.simulators.delta_sm_peer import DeltaSMPeer
from rig.simulators.rig import protocol_peers
from rig.simulators.world import SimWorld

#: The default served sample: road marking RM1 of Spieringhs et al. 2023, as in
#: campaigns/spieringhs2023-rm1.yaml (a client cannot mount a sample over the wire).
PAPER_RM1 = ("retrophong", {"kd": 0.620, "n": 24.0, "k1": 0.158, "k2": 0.0415, "k3": 0.00133, "k4": 5.47})


class ServedRig:
    """`start()` the peers and get the rig configuration clients use; `tick()` often; `stop()`."""

    def __init__(self, base: RigConfig, brdf_model: str, brdf_params: Mapping[str, float], speed: float = 1.0):
        self.speed = speed
        self.world = SimWorld(base, get_model(brdf_model), brdf_params, clock=ServedClock(speed))
        self.peers = protocol_peers(self.world)
        lamp = self.peers["lamp"]
        assert isinstance(lamp, DeltaSMPeer)
        self.lamp = lamp
        self.lamp.exclusive = True          # one client connection at a time
        self.camera = CameraServer(self.world)

    def start(self) -> RigConfig:
        """Listen on every peer; the client rig configuration with their addresses."""
        try:
            addresses = {name: peer.start() for name, peer in self.peers.items()}
            camera_url = self.camera.start()
        except BaseException:
            self.stop()
            raise
        base = self.world.config
        devices = base.devices.model_copy(update={
            **{name: getattr(base.devices, name).model_copy(update={"address": address})
               for name, address in addresses.items()},
            "camera": base.devices.camera.model_copy(update={"driver": SERVED_CAMERA,
                                                             "options": {"address": camera_url}})})
        client = base.model_copy(update={"name": f"{base.name}-served", "simulated": False, "time_scale": self.speed,
                                          "devices": devices})
        return RigConfig.model_validate(client.model_dump())      # validated like a rig file

    def tick(self) -> str | None:
        """Let the lamp supply's watchdog act without a command arriving; what it did, for the log."""
        return self.lamp.check_watchdog()

    def stop(self) -> None:
        self.camera.stop()
        for peer in self.peers.values():
            peer.stop()


def write_rig_file(config: RigConfig, path: Path) -> tuple[int, int]:
    """Write the client rig file at `path`, which must not exist, without the `simulation` section (the
    truths of the served world are not the client's to know); its (device, inode), which `remove_rig_file`
    checks.

    Written whole to a temporary file, then hard-linked to `path`: a client polling for it never reads half
    of it, and the link is exclusive — FileExistsError if anything at all is at `path` (a file, a dangling
    symlink, a device, a FIFO), which is never replaced."""
    text = ("# Written by `rig sim serve`: the simulated rig served on loopback, driven like hardware.\n"
            "# It is valid while that server runs.\n"
            + yaml.safe_dump(config.model_dump(mode="json", exclude={"simulation"}), sort_keys=False))
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "w") as out:
            out.write(text)
            out.flush()
            written = os.fstat(out.fileno())
        os.link(tmp, path)
    finally:
        Path(tmp).unlink(missing_ok=True)
    return written.st_dev, written.st_ino


def remove_rig_file(path: Path, written: tuple[int, int]) -> None:
    """Remove the rig file at `path` if it is still the one `write_rig_file` wrote (same device and inode):
    whatever has replaced it since is someone else's."""
    try:
        found = os.lstat(path)
    except FileNotFoundError:
        return
    if stat.S_ISREG(found.st_mode) and (found.st_dev, found.st_ino) == written:
        path.unlink()
