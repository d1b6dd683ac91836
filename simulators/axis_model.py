"""Motion physics of one simulated axis on the SimClock; no protocol, no I/O.

The controller's pulse generator follows a trapezoidal profile (rig.core.motion)
from the command position to the target: that is the command position. The
load-side encoder reading follows it with an offset that changes during a
move from its old to its new value: half the backlash behind the last
direction of travel, plus the repeatability error of the move
(`positioning_sigma_deg`). The physical angle (what the camera sees) is the
encoder reading plus the axis's zero error, drawn once per run
(`axis_zero_sigma_deg`: zero calibration, sample mounting), which no
read-back shows. The move is in position `settle_s` after the profile ends.
State changes only on commands; everything else is computed from the clock,
so reads taken during a move see it in progress.

Simplifications: a new START during a move restarts from rest at the present
position, and STOP halts at once (the deceleration ramp is not modelled).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from enum import IntEnum

from rig.config.rigfile import AxisConfig
from rig.core.motion import move_time_s, position_at
from rig.simulators.world import SimWorld


class Alarm(IntEnum):
    """The alarms a simulated axis raises, by the codes of the Oriental Motor AZ drives (docs/modbus-drives.md);
    a peer of another protocol translates them to its own flags."""

    DEVIATION = 0x10          # excessive position deviation: stall or obstruction
    OVERTRAVEL = 0x67         # software overtravel: target beyond the soft limits
    OPERATION_DATA = 0x70     # a value of the commanded operation is out of range


@dataclass(frozen=True)
class _Move:
    """One commanded motion; replaced as a whole by the next command, so readers never see half of it."""

    t0: float
    start_deg: float          # command position at t0
    target_deg: float
    speed_deg_s: float
    accel_deg_s2: float
    offset0_deg: float        # encoder minus command position at t0 ...
    offset1_deg: float        # ... and once the move is done
    settle_s: float = 0.0     # in position this long after the profile ends
    extra_s: float = 0.0      # homing: the search for the home sensor after the run
    alarm: int = 0            # alarm raised when the profile ends (injected fault)
    homing: bool = False

    def run_s(self) -> float:
        return move_time_s(self.target_deg - self.start_deg, self.speed_deg_s, self.accel_deg_s2) + self.extra_s


@dataclass(frozen=True)
class AxisState:
    """Everything a status read reports, taken at one instant."""

    busy: bool
    in_position: bool
    alarm: int
    homed: bool
    command_deg: float
    true_deg: float           # physical angle: encoder reading + zero error
    encoder_steps: int
    command_steps: int


class AxisModel:
    def __init__(self, world: SimWorld, name: str, cfg: AxisConfig, *, steps_per_degree: float,
                 backlash_deg: float = 0.002, home_search_s: float = 0.5):
        self.world = world
        self.name = name
        self.cfg = cfg
        self.steps_per_degree = steps_per_degree
        self.backlash_deg = backlash_deg
        self.home_search_s = home_search_s
        self._direction = 1.0                 # of the last travel: the backlash gap lies behind it
        self._latched_alarm = 0
        self._was_homed = False
        self._pending_alarms: list[int] = []
        #: Physical minus encoder angle, fixed for the run.
        self.zero_offset_deg = self._draw_deg(world.config.simulation.axis_zero_sigma_deg)
        rest = -0.5 * backlash_deg
        self._move = _Move(world.clock.now(), 0.0, 0.0, cfg.speed_deg_s, cfg.accel_deg_s2, rest, rest)
        world.axis_truth[name] = self.true_position_deg
        world.axis_zero_deg[name] = self.zero_offset_deg

    # -- what is true now -----------------------------------------------------------------------
    def command_position_deg(self) -> float:
        m = self._move
        return position_at(m.start_deg, m.target_deg, self.world.clock.now() - m.t0, m.speed_deg_s,
                           m.accel_deg_s2)

    def command_speed_deg_s(self) -> float:
        """Signed speed of the command position now (what a drive reports as its feedback speed)."""
        m, h = self._move, 1e-4
        elapsed = self.world.clock.now() - m.t0
        return (position_at(m.start_deg, m.target_deg, elapsed + h, m.speed_deg_s, m.accel_deg_s2)
                - position_at(m.start_deg, m.target_deg, max(elapsed - h, 0.0), m.speed_deg_s, m.accel_deg_s2)
                ) / (elapsed + h - max(elapsed - h, 0.0))

    def encoder_position_deg(self) -> float:
        """What the load-side encoder reads (before quantisation to steps)."""
        m = self._move
        command = self.command_position_deg()
        distance = m.target_deg - m.start_deg
        done = 1.0 if distance == 0.0 else (command - m.start_deg) / distance
        return command + m.offset0_deg + (m.offset1_deg - m.offset0_deg) * done

    def true_position_deg(self) -> float:
        """Physical angle of the load: the encoder reading plus the zero error."""
        return self.encoder_position_deg() + self.zero_offset_deg

    def state(self) -> AxisState:
        m = self._move
        elapsed = self.world.clock.now() - m.t0
        alarm = self._alarm(elapsed)
        settled = elapsed >= m.run_s() + m.settle_s
        command, encoder = self.command_position_deg(), self.encoder_position_deg()
        return AxisState(busy=not settled and not alarm, in_position=settled and not alarm, alarm=alarm,
                         homed=self._homed(elapsed, alarm), command_deg=command,
                         true_deg=encoder + self.zero_offset_deg,
                         encoder_steps=round(encoder * self.steps_per_degree),
                         command_steps=round(command * self.steps_per_degree))

    # -- commands -----------------------------------------------------------------------------
    def start_move(self, target_deg: float, speed_deg_s: float, accel_deg_s2: float) -> None:
        """Ignored while an alarm is present; beyond the soft limits: halt and alarm."""
        if self._present_alarm():
            return
        lo, hi = self.cfg.limits_deg
        if not lo <= target_deg <= hi:
            self.raise_alarm(Alarm.OVERTRAVEL)
            return
        self._begin(target_deg, speed_deg_s, accel_deg_s2)

    def home(self) -> None:
        """Run to the home sensor at 0° (final approach in +), search it, set the homed flag."""
        if self._present_alarm():
            return
        self._begin(0.0, self.cfg.speed_deg_s, self.cfg.accel_deg_s2, homing=True)

    def stop(self) -> None:
        self._fold()
        command, encoder = self.command_position_deg(), self.encoder_position_deg()
        self._move = _Move(self.world.clock.now(), command, command, self._move.speed_deg_s,
                           self._move.accel_deg_s2, encoder - command, encoder - command, self.cfg.settle_s)

    def raise_alarm(self, code: int) -> None:
        """Halt now and hold alarm `code` until it is reset."""
        self.stop()
        self._latched_alarm = code

    def reset_alarm(self) -> None:
        self._fold()
        self._latched_alarm = 0
        self._move = replace(self._move, alarm=0)

    def inject_alarm(self, code: int = Alarm.DEVIATION, moves: int = 1) -> None:
        """The next `moves` moves end in alarm `code` instead of in position."""
        self._pending_alarms.extend([code] * moves)

    # -- internals ----------------------------------------------------------------------------
    def _draw_deg(self, sigma_deg: float) -> float:
        """A normal error from the world's rng; σ = 0 draws nothing, as if the effect did not exist."""
        return float(self.world.rng.normal(0.0, sigma_deg)) if sigma_deg else 0.0

    def _begin(self, target_deg: float, speed_deg_s: float, accel_deg_s2: float, *, homing: bool = False) -> None:
        self._fold()
        command, encoder = self.command_position_deg(), self.encoder_position_deg()
        if homing:
            self._direction = 1.0
            self._was_homed = False
        elif target_deg != command:
            self._direction = math.copysign(1.0, target_deg - command)
        error = self._draw_deg(self.world.config.simulation.positioning_sigma_deg)
        self._move = _Move(self.world.clock.now(), command, target_deg, speed_deg_s, accel_deg_s2,
                           encoder - command, -0.5 * self.backlash_deg * self._direction + error, self.cfg.settle_s,
                           extra_s=self.home_search_s if homing else 0.0,
                           alarm=self._pending_alarms.pop(0) if self._pending_alarms else 0, homing=homing)

    def _alarm(self, elapsed: float) -> int:
        m = self._move
        return self._latched_alarm or (m.alarm if elapsed >= m.run_s() else 0)

    def _present_alarm(self) -> int:
        return self._alarm(self.world.clock.now() - self._move.t0)

    def _homed(self, elapsed: float, alarm: int) -> bool:
        m = self._move
        return self._was_homed or (m.homing and not alarm and elapsed >= m.run_s() + m.settle_s)

    def _fold(self) -> None:
        """Keep what the finished part of the present move established before replacing it."""
        elapsed = self.world.clock.now() - self._move.t0
        alarm = self._alarm(elapsed)
        self._was_homed = self._homed(elapsed, alarm)
        self._latched_alarm = alarm
