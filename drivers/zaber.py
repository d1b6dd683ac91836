"""Zaber rotary stages (X-RSW, X-RST) over the Zaber ASCII protocol, as `Axis` objects.

Our own driver on our line transport rather than zaber-motion: that library is a
large binary-backed package (a Go core behind a Python shim) with its own serial
stack, so it could run neither on `LineTransport` (one retry policy, one event
sink, in-memory replays) nor on the rig clock; the subset we need is a dozen commands.

The protocol (docs/zaber.md): one request line `/d a text[:LRC]`, one reply
`@dd a OK|RJ BUSY|IDLE FLAG data` + CRLF from the addressed device of a daisy
chain; info (`#`) and alert (`!`) lines are skipped. `RJ` is the device's
verdict, and so is a warning flag (a stall, an unexpected limit, no reference
position): persistent DeviceErrors naming the meaning. A missing, cut-off,
garbled or wrongly checksummed reply is transient, retried after a reconnect.
Positions, speeds and accelerations are microsteps on the wire; degrees =
µsteps × 360 / `limit.cycle.dist`, read from the device when it answers it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Generic, TypeVar

from rig.core import events
from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.core.motion import move_time_s
from rig.drivers.interfaces import Axis, TwoAxisPositioner
from rig.drivers.line_instrument import LineInstrument, Query, UnexpectedReply
from rig.drivers.retry import DEFAULT_RETRY, RetryPolicy
from rig.drivers.transport import PortOpener, open_pyserial

T = TypeVar("T")

BAUDRATE = 115200
#: maxspeed data per µstep/s and accel data per µstep/s² (Zaber A/X-series conversion formulas).
SPEED_DATA = 1.6384
ACCEL_DATA = 1.6384 / 10000
#: Reasons of an `RJ` reply.
REASONS = {
    "BADCOMMAND": "unknown command", "BADDATA": "parameter missing or out of range",
    "BADAXIS": "no such axis", "DEVICEONLY": "device-level command sent to an axis",
    "STATUSBUSY": "not allowed while moving", "AGAIN": "busy, try again", "PARKED": "axis parked",
    "NOACCESS": "access level too low", "BADMESSAGEID": "bad message id",
}
#: Warning flags (zaber-motion warning_flags.py): faults F*, warnings W*, notices N*.
FLAGS = {
    "FF": "critical system error", "FN": "peripheral not supported", "FZ": "peripheral inactive",
    "FH": "hardware emergency stop, driver disabled", "FV": "over- or undervoltage, driver disabled",
    "FO": "driver disabled", "FD": "driver disabled", "FC": "current inrush error",
    "FM": "motor temperature error", "FQ": "encoder error", "FI": "index error",
    "FA": "analog encoder sync error", "FR": "overdrive limit exceeded", "FS": "stalled and stopped",
    "FB": "stream bounds error", "FP": "interpolated path deviation", "FE": "limit error",
    "FT": "excessive twist", "WL": "unexpected limit trigger", "WV": "voltage out of range",
    "WT": "controller temperature high", "WS": "stalled with recovery", "WM": "displaced when stationary",
    "WP": "invalid calibration type", "WR": "no reference position", "WH": "device not homed",
    "NC": "manual control", "NI": "movement interrupted", "ND": "stream discontinuity",
    "NR": "value rounded", "NT": "value truncated", "NU": "setting update pending",
    "NJ": "joystick calibrating", "NB": "firmware update mode",
}
NOT_HOMED = frozenset({"WR", "WH"})
#: A reply's flag field when no flag is present.
NO_FLAG = "--"
#: Flags that end a move or mean the position cannot be trusted; the others are reported as events.
ERROR_FLAGS = frozenset({f for f in FLAGS if f.startswith("F")} | {"WL", "WS", "WM"} | NOT_HOMED)
#: Info/alert lines skipped while waiting for a reply, at most.
MAX_SKIPPED = 16


def lrc(body: str) -> str:
    """Longitudinal redundancy check of the text between `/` or `@` and `:`: two's complement of the byte sum."""
    return f"{-sum(body.encode('ascii')) & 0xFF:02X}"


def flag_meaning(flag: str) -> str:
    return f"{flag} ({FLAGS.get(flag, 'undocumented flag')})"


def _flags(data: str) -> tuple[str, ...]:
    """`warnings`' data: `NN F1 F2 …`, a count then that many flags."""
    count, *flags = data.split()
    if int(count) != len(flags):
        raise ValueError(data)
    return tuple(flags)


def _ack(data: str) -> None:
    """Commands that only report their status answer the data `0`."""


# -- the command table (Zaber ASCII protocol manual) ---------------------------------------------
STATUS = Query("", _ack)
HOME = Query("home", _ack)
STOP = Query("stop", _ack)
MOVE_ABS = Query("move abs {}", _ack, "µstep")
POSITION = Query("get pos", int, "µstep")
CYCLE = Query("get limit.cycle.dist", int, "µstep")
MAXSPEED = Query("get maxspeed", int, "1/1.6384 µstep/s")
ACCEL = Query("get accel", int, "10000/1.6384 µstep/s²")
SET_MAXSPEED = Query("set maxspeed {}", _ack, "1/1.6384 µstep/s")
SET_ACCEL = Query("set accel {}", _ack, "10000/1.6384 µstep/s²")
WARNINGS = Query("warnings", _flags)


@dataclass(frozen=True)
class Reply(Generic[T]):
    busy: bool
    flag: str          # the highest-priority warning flag, `--` for none
    value: T


class ZaberRefusal(DeviceError):
    """An `RJ` reply; `reason` is the device's word for it (e.g. BADCOMMAND)."""

    def __init__(self, device: str, message: str, reason: str):
        super().__init__(device, message)
        self.reason = reason


class ZaberChain(LineInstrument):
    """One port (serial path at 115200 8N1, or `socket://host:port`) with a daisy chain of devices.

    `checksum` appends `:LRC` to each request; a reply carrying one is verified either way.
    `events(kind, **fields)` hears retries and warning flags that do not stop a move.
    """

    ROLE: ClassVar[str] = "positioner"          # its role among installed drivers (rig.drivers.registry)

    @classmethod
    def from_rig(cls, *, clock: Clock, settings: Mapping[str, Any], name: str, address: str,
                 axes: Sequence[Sequence[int]] = ((1, 1), (2, 1)), microsteps_per_degree: float | None = None,
                 checksum: bool = True, home: bool = False, timeout_s: float = 1.0,
                 open_port: PortOpener = open_pyserial) -> TwoAxisPositioner:
        """The rig-file contract (rig.drivers.registry): `settings` maps the positioner's two axis names to
        their rig-file sections, `axes` gives each one's (device, axis) address in the same order. Connects
        at once; `home`: home the axes that have no reference position (after power-up)."""
        chain = cls(address, name=name, clock=clock, timeout_s=timeout_s, checksum=checksum, open_port=open_port)
        try:
            made = [chain.axis(device, number, axis_name, cfg.speed_deg_s, cfg.accel_deg_s2, cfg.settle_s,
                               microsteps_per_degree=microsteps_per_degree)
                    for (device, number), (axis_name, cfg) in zip(axes, settings.items(), strict=True)]
            for axis in made:
                if home and not axis.homed:
                    axis.home()
        except BaseException:
            chain.close()
            raise
        return TwoAxisPositioner(name, made[0], made[1])

    def __init__(self, url: str, *, name: str, clock: Clock, timeout_s: float = 1.0, checksum: bool = True,
                 retry: RetryPolicy = DEFAULT_RETRY, open_port: PortOpener = open_pyserial):
        super().__init__(url, name=name, clock=clock, timeout_s=timeout_s, retry=retry, baudrate=BAUDRATE,
                         open_port=open_port)
        self.url = url
        self.checksum = checksum

    def axis(self, device: int, number: int, name: str, speed_deg_s: float, accel_deg_s2: float, settle_s: float,
             *, microsteps_per_degree: float | None = None) -> ZaberAxis:
        return ZaberAxis(self, device, number, name, speed_deg_s, accel_deg_s2, settle_s, microsteps_per_degree)

    def reconnect(self) -> None:
        self.link.reconnect()

    # -- exchanges ----------------------------------------------------------------------------
    def request(self, who: str, device: int, axis: int, query: Query[T], *args: object) -> Reply[T]:
        """One command under the retry policy; `RJ` raises ZaberRefusal (not retried)."""
        line = self.line(device, axis, query.text(*args))
        return self.retrying(line, lambda: self.exchange(who, line, device, axis, query), device=who)

    def line(self, device: int, axis: int, text: str) -> str:
        body = f"{device} {axis} {text}".rstrip()
        return f"/{body}:{lrc(body)}" if self.checksum else f"/{body}"

    def exchange(self, who: str, line: str, device: int, axis: int, query: Query[T]) -> Reply[T]:
        """Write `line`, read up to the addressed device's reply (info, alert and stale lines skipped)."""
        self.link.write_line(line)
        for _ in range(MAX_SKIPPED):
            text = self.link.read_line(line)
            if not text.startswith("@"):
                continue                           # `#` info, `!` alert
            try:
                fields = self._fields(text)
                if (int(fields[0]), int(fields[1])) != (device, axis):
                    continue                       # a late reply of another device
                status, busy, flag, data = fields[2:]
                if status == "RJ":
                    raise ZaberRefusal(who, f"{line!r} rejected: {data} ({REASONS.get(data, 'unknown reason')})",
                                       data)
                return Reply(busy == "BUSY", flag, query.parse(data))
            except UnexpectedReply as exc:
                message = exc.message.format(command=line, reply=text)
            except ValueError:
                message = f"garbled reply to {line!r}: {text!r}"
            raise DeviceError(who, message, transient=True)
        raise DeviceError(who, f"no reply to {line!r} among {MAX_SKIPPED} info/alert lines", transient=True)

    @staticmethod
    def _fields(text: str) -> tuple[str, str, str, str, str, str]:
        """(device, axis, OK|RJ, BUSY|IDLE, flag, data) of a reply line, its checksum verified; a message id
        is dropped."""
        body = text[1:]
        if len(body) > 3 and body[-3] == ":":
            body, check = body[:-3], body[-2:]
            if lrc(body) != check.upper():
                raise UnexpectedReply("reply to {command!r} fails its checksum: {reply!r}")
        words = body.split(" ")
        if len(words) > 2 and words[2].isdigit():
            del words[2]
        if len(words) < 5 or words[2] not in ("OK", "RJ") or words[3] not in ("BUSY", "IDLE") \
                or len(words[4]) != 2 or not (words[0].isdigit() and words[1].isdigit()):
            raise ValueError(text)
        return words[0], words[1], words[2], words[3], words[4], " ".join(words[5:])


class ZaberAxis(Axis):
    #: Rig time between status polls once the predicted move time has passed.
    poll_s = 0.05
    #: Added to the predicted move time so float rounding of clock sums never costs a poll.
    _GUARD_S = 1e-6

    def __init__(self, controller: ZaberChain, device: int, number: int, name: str, speed_deg_s: float,
                 accel_deg_s2: float, settle_s: float, microsteps_per_degree: float | None = None):
        """Reads the microstep size; reads speed and acceleration and sets those that differ from the rig file's
        (a `set` writes the device's flash as well as its RAM, so an unchanged value is not written again);
        reads the warnings (homed or not)."""
        self.controller = controller
        self.device = device
        self.number = number
        self.name = name
        self.settle_s = settle_s
        self.homed = False                            # until the warnings say otherwise: WR is no error yet
        self.microsteps_per_degree = self._microsteps_per_degree(microsteps_per_degree)
        self.speed_data = round(speed_deg_s * self.microsteps_per_degree * SPEED_DATA)
        self.accel_data = max(round(accel_deg_s2 * self.microsteps_per_degree * ACCEL_DATA), 1)
        self.speed_deg_s = self.speed_data / SPEED_DATA / self.microsteps_per_degree      # what the device runs
        self.accel_deg_s2 = self.accel_data / ACCEL_DATA / self.microsteps_per_degree
        # Flags are not judged here: a stall latched before we connected must leave an axis to clear it with;
        # the first move's reply carries it.
        for current, setting, value in ((MAXSPEED, SET_MAXSPEED, self.speed_data),
                                        (ACCEL, SET_ACCEL, self.accel_data)):
            if self.controller.request(self.name, self.device, self.number, current).value != value:
                self.controller.request(self.name, self.device, self.number, setting, value)
        self.homed = not NOT_HOMED & set(self.warnings())
        self._commanded_deg: float | None = None      # where the last command leaves the axis, if known
        self._done_at = 0.0                           # rig time at which that command should be settled

    # -- Axis ---------------------------------------------------------------------------------
    def start_move(self, target_deg: float) -> None:
        if not self.homed:
            raise DeviceError(self.name, f"{self.where()} has no reference position (WR/WH after power-up): "
                                         f"home it before moving")
        start = self.position_deg() if self._commanded_deg is None else self._commanded_deg
        target = round(target_deg * self.microsteps_per_degree)
        self._command(MOVE_ABS, target)
        self._commanded_deg = target / self.microsteps_per_degree
        self._done_at = self.controller.clock.now() + self.move_time_s(start, self._commanded_deg)

    def wait(self, timeout_s: float | None = None) -> None:
        """Sleep the predicted move time, poll until IDLE, then read the warnings the move left."""
        remaining = max(self._done_at - self.controller.clock.now(), 0.0)
        self._settle("move", remaining, 2.0 * remaining + 1.0 if timeout_s is None else timeout_s)

    def position_deg(self) -> float:
        return self._command(POSITION).value / self.microsteps_per_degree

    def is_moving(self) -> bool:
        return self._command(STATUS).busy

    def stop(self) -> None:
        """Decelerate now; a flag in the reply does not stop the stopping, so it is not raised here."""
        self.controller.request(self.name, self.device, self.number, STOP)
        self._commanded_deg = None
        self._done_at = self.controller.clock.now()

    def home(self, timeout_s: float = 120.0) -> None:
        """Run the homing sequence (its reply still carries WR); done when IDLE without WR/WH."""
        start = self._commanded_deg
        self.homed = False                    # WR/WH during the run is expected, not an error
        self.controller.request(self.name, self.device, self.number, HOME)
        self._commanded_deg, self._done_at = 0.0, self.controller.clock.now()
        flags = self._settle("home", 0.0 if start is None else self.move_time_s(start, 0.0), timeout_s)
        if NOT_HOMED & set(flags):
            raise DeviceError(self.name, f"homing ended without a reference position: {self.where()} flags "
                                         f"{', '.join(flag_meaning(f) for f in flags)}")
        self.homed = True

    def move_time_s(self, start_deg: float, target_deg: float) -> float:
        return move_time_s(target_deg - start_deg, self.speed_deg_s, self.accel_deg_s2) + self.settle_s

    def identity(self) -> str:
        return f"Zaber {self.where()}"

    def close(self) -> None:
        self.controller.close()

    # -- further commands ---------------------------------------------------------------------
    def warnings(self) -> tuple[str, ...]:
        """Every warning flag now present (the replies carry only the highest-priority one)."""
        return self.controller.request(self.name, self.device, self.number, WARNINGS).value

    def clear_warnings(self) -> tuple[str, ...]:
        """Clear the flags that can be cleared (a stall, a limit); returns those present before."""
        cleared = Query("warnings clear", _flags)
        return self.controller.request(self.name, self.device, self.number, cleared).value

    def where(self) -> str:
        return f"device {self.device} axis {self.number} on {self.controller.url}"

    # -- helpers ------------------------------------------------------------------------------
    def _microsteps_per_degree(self, configured: float | None) -> float:
        """From `limit.cycle.dist` (µsteps per turn) if the device has one, else the configured value."""
        try:
            cycle: int = self.controller.request(self.name, self.device, self.number, CYCLE).value
        except ZaberRefusal as exc:
            if exc.reason != "BADCOMMAND":
                raise
            cycle = 0
        if cycle > 0:
            return cycle / 360.0
        if configured is None:
            raise DeviceError(self.name, f"{self.where()} answers no limit.cycle.dist (not rotary, or firmware "
                                         f"before 6.20): configure microsteps_per_degree")
        return configured

    def _command(self, query: Query[T], *args: object) -> Reply[T]:
        reply: Reply[T] = self.controller.request(self.name, self.device, self.number, query, *args)
        self._check_flags(query.text(*args) or "status poll", (reply.flag,))
        return reply

    def _settle(self, what: str, predicted_s: float, timeout_s: float) -> tuple[str, ...]:
        """Sleep the predicted time (capped by the timeout), poll until IDLE; the warnings then present.

        The IDLE reply carries the highest-priority flag: `--` means there is none at all, so the
        `warnings` request that would list them is sent only when that reply shows a flag."""
        clock = self.controller.clock
        deadline = clock.now() + timeout_s
        clock.sleep(min(predicted_s + self._GUARD_S, timeout_s))
        while (status := self._command(STATUS)).busy:
            left = deadline - clock.now()
            if left <= 0:
                raise DeviceError(self.name, f"{what} not finished after {timeout_s:.3g} s ({self.where()} BUSY)")
            clock.sleep(min(self.poll_s, left))
        if status.flag == NO_FLAG:
            return ()
        flags = self.warnings()
        self._check_flags(f"after the {what}", flags)
        return flags

    def _check_flags(self, what: str, flags: Sequence[str]) -> None:
        expected = {NO_FLAG} if self.homed else {NO_FLAG, *NOT_HOMED}
        errors = [f for f in flags if f in ERROR_FLAGS and f not in expected]
        for flag in sorted(set(flags) - set(errors) - expected):
            self.controller.events(events.WARNING, device=self.name, what=what, flag=flag_meaning(flag))
        if errors:
            if NOT_HOMED & set(errors):
                self.homed = False
            advice = "; home it" if NOT_HOMED & set(errors) else "; `warnings clear` after fixing the cause"
            raise DeviceError(self.name, f"{what}: {self.where()} flags "
                                         f"{', '.join(flag_meaning(f) for f in errors)}{advice}")

