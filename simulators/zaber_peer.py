"""Protocol peer of a daisy chain of Zaber rotary stages (Zaber ASCII protocol), rebuilt from the public manual.

Sources: zaber.com ASCII protocol manual (message format, replies, `warnings`,
LRC checksums), the settings' unit conversions (maxspeed data = µsteps/s ×
1.6384, accel data = µsteps/s² × 1.6384 / 10000), zaber-motion's flag table
and stphnt/zproto's checksum tests. Each axis drives an `AxisModel`, so moves
take rig time on the world's clock and the true angles reach the world.

What it answers (the peer's choices where the sources are silent are marked):
- `/[device [axis [id]]] command[:LRC]`; device 0 or none: every device answers,
  axis 0 or none: the whole device (home, stop, move and the status poll act on
  all its axes; `get` answers each axis' value, space-separated);
- a reply `@dd a [id] OK|RJ BUSY|IDLE FLAG data` + CRLF, with `:LRC` when the
  request had one; a request with a wrong LRC is not answered (choice);
- `RJ IDLE FLAG BADCOMMAND` for an unknown command, `BADDATA` for a missing or
  out-of-range parameter (a target beyond the rig-file limits), `BADAXIS`;
- the flag: the highest-priority present, F* before W* before N*: `WR` from
  power-up until homed, `FS` after a stall, `WL` after an unexpected limit
  trigger (injected faults: the next move ends in them), until `warnings clear`;
  a move without a reference position is accepted (choice: the driver refuses it);
- reply faults spoil the next reply; `disconnect` (TCP only) drops the connection instead.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

from rig.config.rigfile import AxisConfig
from rig.simulators.axis_model import Alarm, AxisModel
from rig.simulators.faults import ZABER_FAULTS
from rig.simulators.line_peer import LinePeer
from rig.simulators.world import SimWorld

#: Transient faults spoil the next reply; `stall` and `limit` end the next move of an axis in FS / WL.
SPEED_DATA = 1.6384
ACCEL_DATA = 1.6384 / 10000
#: µsteps per turn of our simulated stage (no public X-RSW/X-RST microstep size was found).
CYCLE_DIST = 1_536_000
_ALARM_FLAGS: dict[int, str] = {Alarm.DEVIATION: "FS", Alarm.OVERTRAVEL: "WL"}


def lrc(body: str) -> str:
    return f"{-sum(body.encode('ascii')) & 0xFF:02X}"


class Rejected(Exception):
    def __init__(self, reason: str):
        super().__init__(reason)
        self.reason = reason


@dataclass
class _Axis:
    model: AxisModel
    speed_data: int
    accel_data: int
    referenced: bool

    def flags(self) -> list[str]:
        """Flags present now, highest priority first."""
        state = self.model.state()
        found = [_ALARM_FLAGS.get(state.alarm, "FS")] if state.alarm else []
        if not (self.referenced or state.homed):
            found.append("WR")
        return found



class ZaberPeer(LinePeer):
    """`axes`: (device, axis, name, AxisConfig) per axis of the chain; `cycle_dist`: µsteps per turn, which
    `get limit.cycle.dist` answers unless `answers_cycle_dist` is False (older firmware: BADCOMMAND);
    `homed`: start referenced (as after a homing), not in the power-up state."""

    FAULTS = ZABER_FAULTS

    def __init__(self, world: SimWorld, axes: list[tuple[int, int, str, AxisConfig]], *,
                 medium: Literal["tcp", "pty"] = "tcp", cycle_dist: int = CYCLE_DIST,
                 answers_cycle_dist: bool = True, homed: bool = False, backlash_deg: float = 0.002):
        super().__init__(medium)
        self.world = world
        self.cycle_dist = cycle_dist
        self.answers_cycle_dist = answers_cycle_dist
        per_degree = cycle_dist / 360.0
        self.devices: dict[int, dict[int, _Axis]] = {}
        for device, number, name, cfg in axes:
            model = AxisModel(world, name, cfg, steps_per_degree=per_degree, backlash_deg=backlash_deg)
            self.devices.setdefault(device, {})[number] = _Axis(
                model, round(cfg.speed_deg_s * per_degree * SPEED_DATA),
                max(round(cfg.accel_deg_s2 * per_degree * ACCEL_DATA), 1), homed)
        self._commands: dict[str, Callable[[list[_Axis], list[str]], list[str]]] = {
            "": self._status, "home": self._home, "stop": self._stop, "move": self._move,
            "get": self._get, "set": self._set, "warnings": self._warnings}

    def axis(self, name: str) -> _Axis:
        return next(a for axes in self.devices.values() for a in axes.values() if a.model.name == name)

    def inject(self, fault: str, count: int = 1, axis: str | None = None) -> None:
        """A reply fault (the next `count` replies), or `stall`/`limit`: the next `count` moves of `axis`
        (default: the first) end in FS / WL."""
        self.FAULTS.check(fault, count)
        if fault == "disconnect" and self.medium == "pty":
            raise ValueError("a pty cannot be disconnected: inject 'disconnect' into a TCP peer")
        if fault in self.FAULTS.transient:
            super().inject(fault, count)
            return
        target = self.axis(axis) if axis else next(iter(next(iter(self.devices.values())).values()))
        target.model.inject_alarm(Alarm.DEVIATION if fault == "stall" else Alarm.OVERTRAVEL, moves=count)

    # -- the line -----------------------------------------------------------------------------
    def respond(self, line: bytes) -> bytes | None:
        text = line.decode("ascii", "replace").strip()
        if not text.startswith("/"):
            return None
        body, checked = text[1:], False
        if len(body) >= 3 and body[-3] == ":":
            body, check = body[:-3], body[-2:]
            if lrc(body) != check.upper():
                return None
            checked = True
        replies = [self._reply(device, number, message_id, axes, words, checked)
                   for device, number, message_id, axes, words in self._addressed(body)]
        if not replies:
            return None
        return self.wire("".join(replies)[:-1], self.take_fault())

    def _addressed(self, body: str) -> list[tuple[int, int, str, list[_Axis] | None, list[str]]]:
        """(device, axis, message id, its axes or None for a bad axis, command words) per answering device."""
        words = body.split()
        numbers: list[str] = []
        while words and words[0].isdigit() and len(numbers) < 3:
            numbers.append(words.pop(0))
        device = int(numbers[0]) if numbers else 0
        number = int(numbers[1]) if len(numbers) > 1 else 0
        message_id = numbers[2] if len(numbers) > 2 else ""
        targets = sorted(self.devices) if device == 0 else [device] if device in self.devices else []
        out: list[tuple[int, int, str, list[_Axis] | None, list[str]]] = []
        for d in targets:
            axes = self.devices[d]
            chosen = list(axes.values()) if number == 0 else [axes[number]] if number in axes else None
            out.append((d, number, message_id, chosen, words))
        return out

    def _reply(self, device: int, number: int, message_id: str, axes: list[_Axis] | None, words: list[str],
               checked: bool) -> str:
        status, data = "OK", "0"
        present = [f for a in axes or [] for f in a.flags()]     # as the command found them (`warnings clear`)
        try:
            if axes is None:
                raise Rejected("BADAXIS")
            command = self._commands.get(words[0] if words else "")
            if command is None:
                raise Rejected("BADCOMMAND")
            data = " ".join(command(axes, words[1:]))
        except Rejected as exc:
            status, data = "RJ", exc.reason
        flag = min(present, key=lambda f: "FWN".index(f[0])) if present else "--"
        busy = "BUSY" if any(a.model.state().busy for a in axes or []) else "IDLE"
        body = " ".join(w for w in (f"{device:02d}", str(number), message_id, status, busy, flag, data) if w)
        return f"@{body}:{lrc(body)}\r\n" if checked else f"@{body}\r\n"

    # -- commands -----------------------------------------------------------------------------
    def _status(self, axes: list[_Axis], args: list[str]) -> list[str]:
        return ["0"]

    def _home(self, axes: list[_Axis], args: list[str]) -> list[str]:
        _no_args(args)
        for a in axes:
            a.model.home()
        return ["0"]

    def _stop(self, axes: list[_Axis], args: list[str]) -> list[str]:
        _no_args(args)
        for a in axes:
            a.model.stop()
        return ["0"]

    def _move(self, axes: list[_Axis], args: list[str]) -> list[str]:
        if len(args) != 2 or args[0] != "abs":
            raise Rejected("BADCOMMAND" if not args or args[0] != "abs" else "BADDATA")
        per_degree = self.cycle_dist / 360.0
        target = _integer(args[1]) / per_degree
        for a in axes:
            lo, hi = a.model.cfg.limits_deg
            if not lo <= target <= hi:
                raise Rejected("BADDATA")
        for a in axes:
            a.model.start_move(target, a.speed_data / SPEED_DATA / per_degree, a.accel_data / ACCEL_DATA / per_degree)
        return ["0"]

    def _get(self, axes: list[_Axis], args: list[str]) -> list[str]:
        values: dict[str, Callable[[_Axis], int]] = {
            "pos": lambda a: a.model.state().encoder_steps, "maxspeed": lambda a: a.speed_data,
            "accel": lambda a: a.accel_data}
        if self.answers_cycle_dist:
            values["limit.cycle.dist"] = lambda a: self.cycle_dist
        if len(args) != 1 or args[0] not in values:
            raise Rejected("BADCOMMAND")
        return [str(values[args[0]](a)) for a in axes]

    def _set(self, axes: list[_Axis], args: list[str]) -> list[str]:
        if len(args) != 2 or args[0] not in ("maxspeed", "accel"):
            raise Rejected("BADCOMMAND")
        value = _integer(args[1])
        if value <= 0:
            raise Rejected("BADDATA")
        for a in axes:
            setattr(a, "speed_data" if args[0] == "maxspeed" else "accel_data", value)
        return ["0"]

    def _warnings(self, axes: list[_Axis], args: list[str]) -> list[str]:
        if args not in ([], ["clear"]):
            raise Rejected("BADCOMMAND")
        flags = [f for a in axes for f in a.flags()]
        if args:
            for a in axes:
                a.model.reset_alarm()
        return [f"{len(flags):02d}", *flags]


def _integer(word: str) -> int:
    try:
        return int(word)
    except ValueError:
        raise Rejected("BADDATA") from None


def _no_args(args: list[str]) -> None:
    if args:
        raise Rejected("BADDATA")
