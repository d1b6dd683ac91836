"""Protocol peer of a daisy chain of Zaber rotary stages (Zaber ASCII protocol), rebuilt from the public manual.

Sources: zaber.com ASCII protocol manual (message format, replies, `warnings`,
LRC checksums, commands and settings), the wiki's protocol page (a command ends
in CR and/or LF), the settings' unit conversions (maxspeed data = µsteps/s ×
1.6384, accel data = µsteps/s² × 1.6384 / 10000), zaber-motion's flag table and
stphnt/zproto's checksum tests. Each axis drives an `AxisModel`, so moves take
rig time on the world's clock and the true angles reach the world.

What it answers (the peer's choices where the sources are silent are marked):
- `/[device [axis [id]]] command[:LRC]` ended by CR and/or LF; device 0 or none:
  every device answers, axis 0 or none: the whole device (home, stop, moves and
  the status poll act on all its axes; `get` of an axis setting answers each
  axis' value, space-separated);
- a reply `@dd a [id] OK|RJ BUSY|IDLE FLAG data` + CRLF, with `:LRC` when the
  request had one; a request with a wrong LRC, or longer than
  `comm.packet.size.max`, is not answered (choice);
- `RJ IDLE FLAG BADCOMMAND` for an unknown command or setting (and a write to a
  read-only one: choice), `BADDATA` for a missing or out-of-range parameter (a
  target beyond `limit.min`/`limit.max`), `BADAXIS`, `DEVICEONLY` for a device
  setting read through an axis;
- `help` answers its reply, then `#` info lines (their text is ours);
- `pos` is the axis' microstep (command) position: exactly the target once a
  move is over; `encoder.pos` is the load-side encoder, which lags by the
  backlash and carries the repeatability error;
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

SPEED_DATA = 1.6384
ACCEL_DATA = 1.6384 / 10000
#: µsteps per turn of our simulated stage (no public X-RSW/X-RST microstep size was found).
CYCLE_DIST = 1_536_000
#: `deviceid` of every simulated device: a number of ours, which Zaber's device database does not know.
DEVICE_ID = 99001
#: `system.serial` of device n is SERIAL_BASE + n (ours).
SERIAL_BASE = 990000
#: `comm.packet.size.max`: the longest command line taken (bytes, terminator excluded; our choice).
PACKET_SIZE_MAX = 80
#: `version`, `version.build`: a firmware-7 numbering (ours).
FIRMWARE, BUILD = "7.38", 17000
#: `comm.word.size.max`: the longest word of a command (ours); one packet per command, one setting per `get`.
WORD_SIZE_MAX = 40
#: `resolution`: microsteps per full step (the manual's default).
RESOLUTION = 64
_ALARM_FLAGS: dict[int, str] = {Alarm.DEVIATION: "FS", Alarm.OVERTRAVEL: "WL"}
#: What `help` lists, one info line each.
_HELP = ("home", "move abs|rel|vel <n>", "stop", "estop", "get <setting>", "set maxspeed|accel <n>",
         "tools echo [text]", "warnings [clear]", "help")


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

    def steps(self, deg: float) -> int:
        return round(deg * self.model.steps_per_degree)

    def limits(self) -> tuple[int, int]:
        """`limit.min`, `limit.max`: the rig file's limits in µsteps."""
        lo, hi = self.model.cfg.limits_deg
        return self.steps(lo), self.steps(hi)

    def go(self, target_steps: int, speed_data: int | None = None) -> None:
        """Start a move to `target_steps` (within the limits) at maxspeed, or at `speed_data`."""
        per_degree = self.model.steps_per_degree
        self.model.start_move(target_steps / per_degree, (speed_data or self.speed_data) / SPEED_DATA / per_degree,
                              self.accel_data / ACCEL_DATA / per_degree)


#: Settings read through an axis: name -> value of one axis.
_AXIS_SETTINGS: dict[str, Callable[[_Axis], int]] = {
    "pos": lambda a: a.model.state().command_steps,
    "encoder.pos": lambda a: a.model.state().encoder_steps,
    "maxspeed": lambda a: a.speed_data,
    "accel": lambda a: a.accel_data,
    "limit.min": lambda a: a.limits()[0],
    "limit.max": lambda a: a.limits()[1],
    "resolution": lambda a: RESOLUTION,
    "peripheralid": lambda a: 0,          # an integrated device: no separate peripheral ...
    "peripheral.serial": lambda a: 0,     # ... so no serial number or modification of its own
    "peripheral.hw.modified": lambda a: 0,
}
_WRITABLE = {"maxspeed": "speed_data", "accel": "accel_data"}


class ZaberPeer(LinePeer):
    """`axes`: (device, axis, name, AxisConfig) per axis of the chain; `cycle_dist`: µsteps per turn, which
    `get limit.cycle.dist` answers unless `answers_cycle_dist` is False (older firmware: BADCOMMAND);
    `homed`: start referenced (as after a homing), not in the power-up state."""

    FAULTS = ZABER_FAULTS
    MAX_LINE = PACKET_SIZE_MAX

    def __init__(self, world: SimWorld, axes: list[tuple[int, int, str, AxisConfig]], *,
                 medium: Literal["tcp", "pty"] = "tcp", cycle_dist: int = CYCLE_DIST,
                 answers_cycle_dist: bool = True, homed: bool = False, backlash_deg: float = 0.002):
        super().__init__(medium, terminator=b"\r\n")          # the manual: CR and/or LF
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
        self._commands: dict[str, Callable[[int, int, list[_Axis], list[str]], list[str]]] = {
            "": self._status, "home": self._home, "stop": self._stop, "estop": self._stop, "move": self._move,
            "get": self._get, "set": self._set, "warnings": self._warnings, "tools": self._tools}

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
        """The reply line (CRLF-terminated, `:LRC` if `checked`), then any info lines."""
        status, data, info = "OK", "0", []
        present = [f for a in axes or [] for f in a.flags()]     # as the command found them (`warnings clear`)
        try:
            if axes is None:
                raise Rejected("BADAXIS")
            command = self._commands.get(words[0] if words else "")
            if command is None and words == ["help"]:
                info = list(_HELP)
            elif command is None:
                raise Rejected("BADCOMMAND")
            else:
                data = " ".join(command(device, number, axes, words[1:]))
        except Rejected as exc:
            status, data = "RJ", exc.reason
        flag = min(present, key=lambda f: "FWN".index(f[0])) if present else "--"
        busy = "BUSY" if any(a.model.state().busy for a in axes or []) else "IDLE"
        head = (f"{device:02d}", str(number), message_id)
        lines = [("@", " ".join(w for w in (*head, status, busy, flag, data) if w))]
        lines += [("#", " ".join(w for w in (*head, text) if w)) for text in info]
        return "".join(f"{kind}{body}:{lrc(body)}\r\n" if checked else f"{kind}{body}\r\n" for kind, body in lines)

    # -- commands: (device, axis number (0: the whole device), its axes, the words after the command) -> data --
    def _status(self, device: int, number: int, axes: list[_Axis], args: list[str]) -> list[str]:
        return ["0"]

    def _home(self, device: int, number: int, axes: list[_Axis], args: list[str]) -> list[str]:
        _no_args(args)
        for a in axes:
            a.model.home()
        return ["0"]

    def _stop(self, device: int, number: int, axes: list[_Axis], args: list[str]) -> list[str]:
        """`stop` and `estop` alike: the model halts at once (it has no deceleration ramp)."""
        _no_args(args)
        for a in axes:
            a.model.stop()
        return ["0"]

    def _move(self, device: int, number: int, axes: list[_Axis], args: list[str]) -> list[str]:
        if not args or args[0] not in ("abs", "rel", "vel"):
            raise Rejected("BADCOMMAND")
        if len(args) != 2:
            raise Rejected("BADDATA")
        value = _integer(args[1])
        if args[0] == "vel":
            for a in axes:
                self._velocity(a, value)
            return ["0"]
        targets = [value + (a.model.state().command_steps if args[0] == "rel" else 0) for a in axes]
        for a, target in zip(axes, targets, strict=True):
            lo, hi = a.limits()
            if not lo <= target <= hi:
                raise Rejected("BADDATA")
        for a, target in zip(axes, targets, strict=True):
            a.go(target)
        return ["0"]

    @staticmethod
    def _velocity(a: _Axis, speed_data: int) -> None:
        """`move vel`: run at `speed_data` (signed) until stopped or at `limit.min`/`limit.max`; 0 stops."""
        if speed_data == 0:
            a.model.stop()
            return
        lo, hi = a.limits()
        a.go(hi if speed_data > 0 else lo, abs(speed_data))

    def _get(self, device: int, number: int, axes: list[_Axis], args: list[str]) -> list[str]:
        if len(args) != 1:
            raise Rejected("BADDATA" if args else "BADCOMMAND")
        name = args[0]
        if name in _AXIS_SETTINGS:
            return [str(_AXIS_SETTINGS[name](a)) for a in axes]
        if name == "limit.cycle.dist" and self.answers_cycle_dist:
            return [str(self.cycle_dist) for _ in axes]
        values = {"deviceid": DEVICE_ID, "system.serial": SERIAL_BASE + device, "version": FIRMWARE,
                  "version.build": BUILD, "device.hw.modified": 0, "system.axiscount": len(self.devices[device]),
                  "comm.packet.size.max": PACKET_SIZE_MAX, "comm.command.packets.max": 1,
                  "comm.word.size.max": WORD_SIZE_MAX, "get.settings.max": 1}       # the device's own settings
        if name not in values:
            raise Rejected("BADCOMMAND")
        if number:
            raise Rejected("DEVICEONLY")
        return [str(values[name])]

    def _set(self, device: int, number: int, axes: list[_Axis], args: list[str]) -> list[str]:
        if len(args) != 2:
            raise Rejected("BADDATA" if args else "BADCOMMAND")
        if args[0] not in _WRITABLE:
            raise Rejected("BADCOMMAND")
        value = _integer(args[1])
        if value <= 0:
            raise Rejected("BADDATA")
        for a in axes:
            setattr(a, _WRITABLE[args[0]], value)
        return ["0"]

    def _warnings(self, device: int, number: int, axes: list[_Axis], args: list[str]) -> list[str]:
        if args not in ([], ["clear"]):
            raise Rejected("BADCOMMAND")
        flags = [f for a in axes for f in a.flags()]
        if args:
            for a in axes:
                a.model.reset_alarm()
        return [f"{len(flags):02d}", *flags]

    def _tools(self, device: int, number: int, axes: list[_Axis], args: list[str]) -> list[str]:
        """`tools echo [text]`: the text back (`0` for none)."""
        if not args or args[0] != "echo":
            raise Rejected("BADCOMMAND")
        return args[1:] or ["0"]


def _integer(word: str) -> int:
    try:
        return int(word)
    except ValueError:
        raise Rejected("BADDATA") from None


def _no_args(args: list[str]) -> None:
    if args:
        raise Rejected("BADDATA")
