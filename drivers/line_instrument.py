"""Line instruments as tables of commands over one line transport and one retry policy.

PyMeasure's instruments are the model: a driver declares its commands (the
text template, whether the instrument answers, how the answer is parsed and
in which unit) and this base does the exchanges. A reply that `parse` rejects
is garbled, a transient fault retried like a timeout; a parser may say more
precisely what was wrong by raising `UnexpectedReply`.

How a setting is confirmed is declared once per driver (`confirmation`, as
PyMeasure's `check_set_errors` hook): by an acknowledgement line (the P-9710's
bare LF, the FW102C's echo and prompt), by reading the error queue after it
(SCPI's `SYSTem:ERRor?`, the SM15K), or not at all. `put` makes one setting's
exchange with its confirmation, `apply` the same under the retry policy.

A driver whose connection reports events before anyone can attach a sink (the
lamp supply's watchdog found expired) declares `holds_events`: they are held
here and handed to the first sink attached.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar, Generic, TypeVar

from rig.core import events
from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.drivers.retry import EventSink, RetryingDevice, RetryPolicy, no_events
from rig.drivers.transport import LineTransport, PortOpener, open_pyserial

T = TypeVar("T")


class UnexpectedReply(ValueError):
    """Raised by a parser: `message` may name `{command!r}` and `{reply!r}`; the reply counts as transient."""

    def __init__(self, message: str):
        super().__init__(message)
        self.message = message


@dataclass(frozen=True)
class Setting:
    """A command that changes the instrument's state and answers no value; `template` takes the parameters
    (`str.format`). How the instrument confirms it is the driver's `confirmation`."""

    template: str
    unit: str = ""

    def text(self, *args: object) -> str:
        return self.template.format(*args)


@dataclass(frozen=True)
class Query(Generic[T]):
    """A command answered by one line, turned into a value (in `unit`) by `parse`."""

    template: str
    parse: Callable[[str], T]
    unit: str = ""

    def text(self, *args: object) -> str:
        return self.template.format(*args)


@dataclass(frozen=True)
class Acknowledgement:
    """A setting is confirmed by one reply line that is empty (after the framing, e.g. an echo is stripped);
    `what` names that line in the message when something else comes back (a transient fault)."""

    what: str

    def __call__(self, reply: str) -> None:
        if reply:
            raise UnexpectedReply(f"{{command!r}} answered {{reply!r}} instead of {self.what}")


@dataclass(frozen=True)
class ErrorQueue:
    """A setting is confirmed by draining the instrument's error queue after it: `query` answers
    `(code, entry)`, code 0 when the queue is empty; at most `size` entries are read. An entry is an
    objection to the setting."""

    query: Query[tuple[int, str]]
    size: int


#: How a driver's settings are confirmed: an acknowledgement line, the error queue, or None (not at all).
Confirmation = Acknowledgement | ErrorQueue | None


class LineInstrument(RetryingDevice):
    """An ASCII instrument on a pyserial URL (`socket://host:port`, a serial port, a pty path)."""

    #: How the instrument confirms a setting (declared per driver; the default: it does not).
    confirmation: ClassVar[Confirmation] = None
    #: Whether events reported before a sink is attached (during the connection) are held for the first sink
    #: attached; otherwise they go nowhere, as RetryingDevice's `no_events`.
    holds_events: ClassVar[bool] = False

    def __init__(self, url: str, *, name: str, clock: Clock, timeout_s: float, retry: RetryPolicy,
                 baudrate: int = 9600, terminator: bytes = b"\n", write_terminator: bytes | None = None,
                 echo: bool = False, open_port: PortOpener = open_pyserial):
        """`terminator`, `write_terminator`, `echo`: the framing, as `LineTransport` takes it."""
        self._held: list[tuple[str, dict[str, Any]]] = []
        super().__init__(name, clock, retry)
        self._sink: EventSink | None = None      # RetryingDevice attached `no_events`: no sink yet
        self.link = LineTransport(name, url, terminator=terminator, timeout_s=timeout_s, baudrate=baudrate,
                                  write_terminator=write_terminator, echo=echo, open_port=open_port)

    def reconnect(self) -> None:
        self.link.reconnect()

    def close(self) -> None:
        self.link.close()

    # -- events, held until a sink is attached ----------------------------------------------------
    @property
    def events(self) -> EventSink:
        if self._sink is not None:
            return self._sink
        return self._hold if self.holds_events else no_events

    @events.setter
    def events(self, sink: EventSink) -> None:
        self._sink = sink
        held, self._held = self._held, []
        for kind, fields in held:
            sink(kind, **fields)

    def _hold(self, kind: str, **fields: Any) -> None:
        self._held.append((kind, fields))

    # -- one exchange, no retry ---------------------------------------------------------------------
    def send(self, setting: Setting, *args: object) -> str:
        """Write a setting, unconfirmed; returns the line sent (errors name it)."""
        line = setting.text(*args)
        self.link.write_line(line)
        return line

    def put(self, setting: Setting, *args: object, timeout_s: float | None = None,
            tolerate_errors: bool = False) -> None:
        """Write a setting and confirm it as the driver declares (`confirmation`). An objection from the error
        queue is a refusal, a persistent DeviceError naming the line; with `tolerate_errors` (on the way to a
        safe state, where a stale entry must not stop the way) an event `device_errors` instead. `timeout_s`
        replaces the link's timeout for an acknowledgement (one that comes when a move ends)."""
        line = self.send(setting, *args)
        objections = self.confirm(line, timeout_s)
        if objections and tolerate_errors:
            self.events(events.DEVICE_ERRORS, device=self.name, what=line, errors=objections)
        elif objections:
            raise DeviceError(self.name, f"{line!r} refused: {'; '.join(objections)}")

    def confirm(self, line: str, timeout_s: float | None = None) -> list[str]:
        """The confirmation hook: the instrument's objections to the setting `line` just sent (none: [])."""
        confirmation = self.confirmation
        if isinstance(confirmation, Acknowledgement):
            self._answer(line, confirmation, timeout_s)
        elif isinstance(confirmation, ErrorQueue):
            return self.drain(confirmation.query, confirmation.size)
        return []

    def ask(self, query: Query[T], *args: object, timeout_s: float | None = None) -> T:
        """One query; a reply `parse` rejects is a transient DeviceError naming command and reply.
        `timeout_s` replaces the link's timeout for this reply (a slow measurement)."""
        line = query.text(*args)
        self.link.write_line(line)
        return self._answer(line, query.parse, timeout_s)

    def _answer(self, line: str, parse: Callable[[str], T], timeout_s: float | None) -> T:
        """Read the reply to `line`: the instrument's refusal raised, the rest parsed."""
        reply = self.link.read_line(line, timeout_s)
        self.check_refusal(line, reply)
        try:
            return parse(reply)
        except UnexpectedReply as exc:
            message = exc.message.format(command=line, reply=reply)
        except ValueError:
            message = f"garbled reply to {line!r}: {reply!r}"
        raise DeviceError(self.name, message, transient=True)

    def drain(self, queue: Query[tuple[int, str]], size: int,
              ask: Callable[[Query[tuple[int, str]]], tuple[int, str]] | None = None) -> list[str]:
        """Read a queue (errors, warnings) with `ask` (default: one exchange each) until its code 0, at most
        `size` entries; the entries read before it."""
        entries = []
        for _ in range(size):
            code, entry = (ask or self.ask)(queue)
            if code == 0:
                break
            entries.append(entry)
        return entries

    def check_refusal(self, line: str, reply: str) -> None:
        """Raise the instrument's own error reply (e.g. the P-9710's `?x`) as a persistent DeviceError;
        the default: the instrument has none (a refusal then shows elsewhere, e.g. an error queue)."""

    # -- under the retry policy -------------------------------------------------------------------
    def query(self, query: Query[T], *args: object) -> T:
        """One query under the retry policy, reconnecting before each retry."""
        return self.retrying(query.text(*args), lambda: self.ask(query, *args))

    def apply(self, setting: Setting, *args: object, policy: RetryPolicy | None = None,
              tolerate_errors: bool = False) -> None:
        """One setting and its confirmation (`put`) under `policy` (default: the driver's), reconnecting
        before each retry: a setting whose confirmation was lost is sent again, so it must be absolute (a
        level, a state), never relative."""
        self.retrying(setting.text(*args), lambda: self.put(setting, *args, tolerate_errors=tolerate_errors),
                      policy=policy)


def number(reply: str) -> float:
    """A plain decimal reply."""
    return float(reply)


def choice(replies: dict[str, T]) -> Callable[[str], T]:
    """A parser for one of a fixed set of replies (case-insensitive)."""
    def parse(reply: str) -> T:
        if reply.upper() not in replies:
            raise ValueError(reply)
        return replies[reply.upper()]
    return parse
