"""The engine's moves: stage and arm together, never through a forbidden zone, with a timeout.

Motor positions are (stage_vertical, stage_normal, arm_azimuth, arm_polar) in degrees, the
order of the plan and of brdf.csv; a point's read-back comes with the BRDF angles it gives (`arrive`).
Both positioners start before either is waited for, so the four axes run at once; a move may be
started and waited for later (the engine starts the move to the next point before merging the frames
of this one).

With a geometry calibration (the rig file's `geometry.calibration_file`, docs/geometry-calibration.md)
every axis's position is the physical angle, encoder reading + the axis's zero offset; after an
alignment (rig.acquisition.alignment) the arm's positions are also relative to the aligned zero: the
engine's targets and read-backs are the corrected ones, and only the commands and encoder readings
carry the offsets.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from rig.config.rigfile import RigConfig
from rig.core import events
from rig.drivers.interfaces import RigDevices
from rig.physics.geometry import BrdfAngles, forward_deg
from rig.planning.collisions import path_crosses, zones_of
from rig.planning.ordering import travel_time_s
from rig.planning.points import Motors, PlannedPoint


class CollisionError(RuntimeError):
    """A move would cross a forbidden zone of the rig configuration; nothing moved."""


class Mover:
    """Where the axes are (as far as the engine knows) and the move under way, if any."""

    #: Moves may take this much longer than predicted before the axis counts as stuck.
    MOVE_TIMEOUT_FACTOR = 2.0
    MOVE_TIMEOUT_MARGIN_S = 10.0

    def __init__(self, devices: RigDevices, rig: RigConfig):
        self.dev = devices
        self.rig = rig
        #: Encoder readings (arm azimuth, arm polar) at the aligned zero; (0, 0) until aligned.
        self.arm_zero_deg: tuple[float, float] = (0.0, 0.0)
        #: Each axis's zero offset from the geometry calibration (physical = encoder + offset); zeros without one.
        calibration = rig.geometry.calibration
        self.offsets_deg: Motors = calibration.zero_offsets_deg if calibration is not None else (0.0, 0.0, 0.0, 0.0)
        self.position: Motors = self.read_back()
        self.moving_to: Motors | None = None     # target of a move started and not yet waited for

    def read_back(self) -> Motors:
        """The encoders' positions plus the calibration's offsets (the arm's relative to its aligned zero), the
        values the dataset records."""
        stage, arm = self.dev.stage.positions_deg(), self.dev.arm.positions_deg()
        off = self.offsets_deg
        return (stage[0] + off[0], stage[1] + off[1], arm[0] + off[2] - self.arm_zero_deg[0],
                arm[1] + off[3] - self.arm_zero_deg[1])

    def align(self, arm_zero_deg: tuple[float, float]) -> None:
        """From now on the arm's positions are relative to `arm_zero_deg` (encoder readings)."""
        self.arm_zero_deg = arm_zero_deg
        self.resync()

    def resync(self) -> None:
        """Take the read-back as the position (after a device error left it unknown)."""
        self.position = self.read_back()

    def start(self, target: Motors) -> None:
        """Start all four axes together toward `target`, never through a forbidden zone.

        The planner already routes around the zones; this guards the moves it did not
        plan: the first one of a resume, a retry's, the park.
        """
        if self.moving_to is not None:          # interrupted on its way: where is it now?
            self.resync()
        zone = path_crosses(self.position, target, zones_of(self.rig), self.rig.axes)
        if zone is not None:
            raise CollisionError(f"move from {self.position} to {target} (deg) would cross forbidden zone {zone!r}")
        off = self.offsets_deg
        self.dev.stage.start_move(target[0] - off[0], target[1] - off[1])
        self.dev.arm.start_move(target[2] - off[2] + self.arm_zero_deg[0], target[3] - off[3] + self.arm_zero_deg[1])
        self.moving_to = target

    def move(self, target: Motors) -> None:
        """Be at `target`: wait for the move already under way there, else start one, then wait."""
        if self.moving_to != target:
            self.start(target)
        predicted_s = float(travel_time_s(self.rig.axes, np.asarray(self.position, float), np.asarray(target, float)))
        timeout_s = self.MOVE_TIMEOUT_FACTOR * predicted_s + self.MOVE_TIMEOUT_MARGIN_S
        self.dev.stage.wait(timeout_s)
        self.dev.arm.wait(timeout_s)
        self.position, self.moving_to = target, None

    def arrive(self, point: PlannedPoint) -> tuple[Motors, BrdfAngles]:
        """Be at `point`'s motor positions; where the axes are then (the read-back, which the dataset records) and
        the BRDF angles they give (rig.physics.geometry.forward_deg, φ at a pole as `point` says): the point's
        geometry from one call."""
        self.move(point.motors_deg)
        motors = self.read_back()
        return motors, forward_deg(*motors, phi_i_at_pole_deg=point.phi_i_deg, phi_o_at_pole_deg=point.phi_o_deg)

    def park(self, target: Motors, event: Callable[..., None]) -> None:
        """Go to `target` at the end of a run; a move that would cross a forbidden zone is left out, said in an
        event (`park_skipped`), never raised: the exit path goes on to make the rig safe."""
        try:
            self.move(target)
        except CollisionError as exc:
            event(events.PARK_SKIPPED, reason=str(exc))
            return
        event(events.PARKED, position_deg=list(target))
