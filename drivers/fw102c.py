"""Thorlabs FW102C / FW212C motorised filter wheel on its USB virtual COM port (115200 8N1), as the Attenuator.

The protocol is the manual's (FW102C manual Rev H 2014, p. 11; contract in
docs/fw102c.md): a lower-case command + CR; the wheel echoes the command + CR,
then its reply + CR (a setting has none), then the prompt `> `, which ends no
line: the link reads up to the prompt and checks and strips the echo.
`Command error CMD_NOT_DEFINED` / `CMD_ARG_INVALID` in place of a reply is the
wheel's own refusal, a persistent DeviceError naming the command; a garbled,
echo-less or missing reply is a transient fault, retried after a reconnect.

The prompt after `pos=n` comes only when the wheel has stopped, about 1 s per
position at high speed, so the driver waits twice that (plus 1 s) for the
shorter way round, as odemis does, and then asks `pos?`: a wheel that did not
get there (jammed, held) is a persistent error, which no retry mends.

Connecting (and every retry's reconnect): a bare CR whose answer is read and
dropped (the first command after power-up can be spoilt by stray NUL bytes),
`*idn?` (a Thorlabs FW wheel, or refused), `pcount?`, high speed (`speed=1`),
sensors off while idle (`sensors=0`: their light would reach the camera), and
`pos?`. `save` and `pcount=` are never sent: they rewrite the wheel's stored
defaults.
"""

from __future__ import annotations

import re
from typing import Any

from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.drivers.interfaces import Attenuator
from rig.drivers.line_instrument import Acknowledgement, LineInstrument, Query, Setting, UnexpectedReply
from rig.drivers.retry import DEFAULT_RETRY, RetryPolicy
from rig.drivers.transport import PortOpener, open_pyserial

BAUDRATE = 115200
PROMPT = b"> "
#: A move at high speed (`speed=1`) takes about this long per position of travel.
MOVE_S_PER_POSITION = 1.0
#: The driver waits this many times the expected move (plus 1 s) for the prompt before calling it lost.
MOVE_MARGIN = 2.0
#: `*idn?` answers e.g. `THORLABS FW102C/FW212C Filter Wheel version 1.04`.
_IDENTITY = re.compile(r"THORLABS FW\d{3}C\b")
#: The wheels made: 6 or 12 positions.
WHEEL_SIZES = (6, 12)


def _wheel_size(reply: str) -> int:
    if reply not in {str(n) for n in WHEEL_SIZES}:
        raise UnexpectedReply("{command!r} answered {reply!r}, not a wheel of 6 or 12 positions")
    return int(reply)


# -- the command table (manual p. 11) -------------------------------------------------------------
WAKE = Setting("")                          # a bare CR
IDENTITY = Query("*idn?", str)
POSITION_COUNT = Query("pcount?", _wheel_size)
SPEED = Setting("speed={:d}")               # 0 slow, 1 high
SENSORS = Setting("sensors={:d}")           # 0 off while idle, 1 always on
MOVE = Setting("pos={:d}")
POSITION = Query("pos?", int)


class FW102C(LineInstrument, Attenuator):
    """Connects on construction. `timeout_s` bounds every reply but a move's, which gets
    `move_timeout_s`. `events(kind, **fields)` hears retries."""

    #: A setting is answered by its echo and the prompt alone (`Command error …` is the wheel's refusal).
    confirmation = Acknowledgement("only its echo and the prompt")

    def __init__(self, url: str, *, clock: Clock, name: str = "attenuator", timeout_s: float = 1.0,
                 retry: RetryPolicy = DEFAULT_RETRY, open_port: PortOpener = open_pyserial):
        super().__init__(url, name=name, clock=clock, timeout_s=timeout_s, retry=retry, baudrate=BAUDRATE,
                         terminator=PROMPT, write_terminator=b"\r", echo=True, open_port=open_port)
        self.positions = 0
        self._identity = ""
        self._position = 0           # as last read back; 0 while unknown (a move that did not finish)
        try:
            self.retrying("connect", self.reconnect, reconnect=False)    # reconnect() opens the port itself
        except BaseException:
            self.link.close()
            raise

    @classmethod
    def from_rig(cls, *, clock: Clock, settings: Any, address: str, timeout_s: float = 1.0) -> FW102C:
        """The rig-file contract (rig.drivers.registry): `settings` (the rig file's `attenuator` section)
        holds the filters' transmissions, which the driver does not need."""
        return cls(address, clock=clock, timeout_s=timeout_s)

    # -- Attenuator ------------------------------------------------------------------------------
    def identity(self) -> str:
        return f"{self._identity} ({self.positions} positions)"

    def move_to(self, position: int) -> None:
        """Turn filter `position` into the beam and confirm it with `pos?`; nothing is sent if it is there."""
        if not 1 <= position <= self.positions:
            raise DeviceError(self.name, f"no filter position {position}: the wheel has positions "
                                         f"1 … {self.positions}")
        self.retrying(MOVE.text(position), lambda: self._move(position))

    def position(self) -> int:
        return self.retrying(POSITION.text(), self._read_position)

    def move_timeout_s(self, start: int, target: int) -> float:
        """How long the prompt after `pos=target` may take: twice (the move the shorter way round + 1 s);
        from an unknown `start` (0), the move is half the wheel."""
        steps = abs(target - start) % self.positions
        travel = min(steps, self.positions - steps) if start else self.positions // 2
        return MOVE_MARGIN * (MOVE_S_PER_POSITION * travel + 1.0)

    # -- protocol --------------------------------------------------------------------------------
    def reconnect(self) -> None:
        """(Re)open the port, wake the wheel, check it is a Thorlabs wheel and set it up (a retry's way
        back too: a power-cycled wheel has its stored speed and sensor mode again)."""
        self.link.reconnect()
        self._wake()
        identity = self.ask(IDENTITY)
        if not _IDENTITY.match(identity.upper()):
            raise DeviceError(self.name, f"{IDENTITY.text()!r} answered {identity!r}: not a Thorlabs FW102C/FW212C "
                                         f"filter wheel")
        self.positions = self.ask(POSITION_COUNT)
        self.put(SPEED, 1)
        self.put(SENSORS, 0)
        self._read_position()
        self._identity = identity

    def _wake(self) -> None:
        """A bare CR, and whatever comes back (a prompt, an error, stray NULs, nothing) read and dropped,
        so that the first real command is not the one that meets a freshly powered wheel's noise."""
        line = self.send(WAKE)
        try:
            self.link.read_line(line)
        except DeviceError:
            pass        # whatever the wheel made of it: the next command starts afresh

    def _move(self, target: int) -> None:
        """One `pos=` and its confirmation; the position is unknown until that confirmation."""
        start = self._position
        if start == target:
            return
        self._position = 0
        self.put(MOVE, target, timeout_s=self.move_timeout_s(start, target))
        reached = self._read_position()
        if reached != target:
            raise DeviceError(self.name, f"{MOVE.text(target)!r} ended at position {reached}, not {target} "
                                         f"(is the wheel jammed or held?)")

    def _read_position(self) -> int:
        position = self.ask(POSITION)
        if not 1 <= position <= self.positions:
            raise DeviceError(self.name, f"{POSITION.text()!r} answered {position}, not a position "
                                         f"1 … {self.positions}", transient=True)
        self._position = position
        return position

    def check_refusal(self, line: str, reply: str) -> None:
        """`Command error <code>` is the wheel's verdict on the command: persistent."""
        if reply.startswith("Command error"):
            raise DeviceError(self.name, f"{line!r} refused: {reply}")
