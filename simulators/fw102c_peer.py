"""Protocol peer of the Thorlabs FW102C / FW212C filter wheel on a pseudo-terminal, rebuilt from its manual.

The driver talks to it exactly as to the wheel's USB virtual COM port: the
peer owns a pty pair and hands out the slave path (`/dev/pts/N`), which
pyserial opens like any tty (see `rig.simulators.line_peer`).

What it answers follows the FW102C manual (Rev H 2014, p. 11) and the exchanges
captured in delmic/odemis' simulator of the unit (src/odemis/driver/tlfw.py):

- a command is a line ending in CR; each is echoed with its CR, followed by
  the reply + CR if the command has one, then the prompt `> ` (no line end);
- `*idn?`, `pos?`, `pcount?`, `speed?`, `trig?`, `sensors?`, `baud?` answer
  their value; `pos=n`, `pcount=n`, `speed=n`, `trig=n`, `sensors=n`,
  `baud=n`, `save` set (the manual's whole keyword table);
- an unknown command (commands are lower case; a bare CR is an empty
  command: odemis' simulator treats it so too) answers `Command error
  CMD_NOT_DEFINED` + LF, a bad argument `Command error CMD_ARG_INVALID` + LF;
- the prompt after `pos=n` comes when the move ends: 1 s per position at high
  speed, 2 s slow, the shorter way round (odemis' timing); the peer spends
  that rig time on the world's clock.

Powers up on position 1, slow, sensors on, 115200 baud (our choice: the stored
defaults of a unit are whatever `save` last stored). The trigger input is not
modelled, nor is the link rate `baud=0` selects (a pty has none): the setting
is kept and read back. Nor are the manual's arrow keys (up/down: one position
on), which are keystrokes of a terminal, not command lines.
"""

from __future__ import annotations

import re

from rig.simulators.faults import ATTENUATOR_FAULTS
from rig.simulators.line_peer import LinePeer
from rig.simulators.world import SimWorld

IDENTITY = "THORLABS FW102C/FW212C Filter Wheel version 1.04"
PROMPT = b"> "
NOT_DEFINED = "Command error CMD_NOT_DEFINED\n"
ARG_INVALID = "Command error CMD_ARG_INVALID\n"
#: Seconds per position of travel at speed 0 (slow) and 1 (high).
MOVE_S_PER_POSITION = (2.0, 1.0)
WHEEL_SIZES = (6, 12)
_ARGUMENT = re.compile(r"\d{1,3}")


class CommandError(Exception):
    """The `Command error …` line a command is answered with."""


class FW102CPeer(LinePeer):
    """Simulated filter wheel of `positions` (6 or 12) filters; `position` is the filter in the beam.

    Faults: `no_reply` (the wheel takes no notice of the next line), `garbled`
    (line noise on the next answer: high bits set, the prompt intact), `stuck`
    (the next move runs its time but the wheel does not turn).
    """

    FAULTS = ATTENUATOR_FAULTS

    def __init__(self, world: SimWorld, positions: int = 6, *, position: int = 1):
        if positions not in WHEEL_SIZES or not 1 <= position <= positions:
            raise ValueError(f"a wheel of 6 or 12 positions at one of them, not {position} of {positions}")
        super().__init__("pty", terminator=b"\r")
        self.world = world
        self.positions = positions
        self.position = position
        self.speed = 0
        self.trigger = 0
        self.sensors = 1
        self.baud = 1                                 # 0: 9600, 1: 115200
        self.saved: dict[str, int] | None = None      # what `save` stored last
        self._stuck = 0

    def inject(self, fault: str, count: int = 1) -> None:
        """Reply faults spoil the next `count` answers; `stuck` holds the wheel for the next `count` moves."""
        if fault != "stuck":
            super().inject(fault, count)
            return
        self.FAULTS.check(fault, count)
        with self._lock:
            self._stuck += count

    # -- the line ---------------------------------------------------------------------------------
    def respond(self, line: bytes) -> bytes | None:
        """The echo, the answer (if any) and the prompt, as one write; a fault spoils or drops them."""
        fault = self.take_fault()
        if fault == "no_reply":
            return None
        try:
            reply = self.execute(line.decode("ascii"))
        except UnicodeDecodeError:
            reply = NOT_DEFINED
        except CommandError as exc:
            reply = str(exc)
        data = line + b"\r" + (b"" if reply is None else reply.encode("ascii") + b"\r")
        if fault == "garbled":
            data = bytes(b | 0x80 for b in data)
        return data + PROMPT

    def execute(self, command: str) -> str | None:
        """One command: its answer, None for a setting, or CommandError."""
        if command == "*idn?":
            return IDENTITY
        if command == "save":
            self.saved = self._settings()
            return None
        if command.endswith("?") and command[:-1] in self._settings():
            return str(self._settings()[command[:-1]])
        name, equals, argument = command.partition("=")
        setters = {"pos": self._move, "pcount": self._set_count, "speed": self._set_speed,
                   "trig": self._set_trigger, "sensors": self._set_sensors, "baud": self._set_baud}
        if not equals or name not in setters:
            raise CommandError(NOT_DEFINED)
        if not _ARGUMENT.fullmatch(argument):
            raise CommandError(ARG_INVALID)
        setters[name](int(argument))
        return None

    def _settings(self) -> dict[str, int]:
        return {"pos": self.position, "pcount": self.positions, "speed": self.speed, "trig": self.trigger,
                "sensors": self.sensors, "baud": self.baud}

    # -- settings ---------------------------------------------------------------------------------
    def _move(self, target: int) -> None:
        """Turn the shorter way round, spending the move's rig time before the prompt; a stuck wheel
        spends it too, without turning."""
        if not 1 <= target <= self.positions:
            raise CommandError(ARG_INVALID)
        steps = abs(target - self.position)
        travel = min(steps, self.positions - steps)
        self.world.spend_s(travel * MOVE_S_PER_POSITION[self.speed])
        with self._lock:
            stuck = travel > 0 and self._stuck > 0
            if stuck:
                self._stuck -= 1
        if not stuck:
            self.position = target

    def _set_count(self, count: int) -> None:
        if count not in WHEEL_SIZES:
            raise CommandError(ARG_INVALID)
        self.positions = count
        self.position = min(self.position, count)

    def _set_speed(self, speed: int) -> None:
        self.speed = _flag(speed)

    def _set_trigger(self, trigger: int) -> None:
        self.trigger = _flag(trigger)

    def _set_sensors(self, sensors: int) -> None:
        self.sensors = _flag(sensors)

    def _set_baud(self, baud: int) -> None:
        self.baud = _flag(baud)


def _flag(value: int) -> int:
    if value not in (0, 1):
        raise CommandError(ARG_INVALID)
    return value
