"""Line instruments as tables of commands over one line transport and one retry policy.

PyMeasure's instruments are the model: a driver declares its commands (the
text template, whether the instrument answers, how the answer is parsed and
in which unit) and this base does the exchanges. A reply that `parse` rejects
is garbled, a transient fault retried like a timeout; a parser may say more
precisely what was wrong by raising `UnexpectedReply`.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.drivers.retry import RetryingDevice, RetryPolicy
from rig.drivers.transport import LineTransport, PortOpener, open_pyserial

T = TypeVar("T")


class UnexpectedReply(ValueError):
    """Raised by a parser: `message` may name `{command!r}` and `{reply!r}`; the reply counts as transient."""

    def __init__(self, message: str):
        super().__init__(message)
        self.message = message


@dataclass(frozen=True)
class Setting:
    """A command the instrument does not answer; `template` takes the parameters (`str.format`)."""

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


class LineInstrument(RetryingDevice):
    """An ASCII instrument on a pyserial URL (`socket://host:port`, a serial port, a pty path)."""

    def __init__(self, url: str, *, name: str, clock: Clock, timeout_s: float, retry: RetryPolicy,
                 baudrate: int = 9600, terminator: bytes = b"\n", write_terminator: bytes | None = None,
                 echo: bool = False, open_port: PortOpener = open_pyserial):
        """`terminator`, `write_terminator`, `echo`: the framing, as `LineTransport` takes it."""
        super().__init__(name, clock, retry)
        self.link = LineTransport(name, url, terminator=terminator, timeout_s=timeout_s, baudrate=baudrate,
                                  write_terminator=write_terminator, echo=echo, open_port=open_port)

    def reconnect(self) -> None:
        self.link.reconnect()

    def close(self) -> None:
        self.link.close()

    # -- one exchange, no retry ---------------------------------------------------------------------
    def send(self, setting: Setting, *args: object) -> str:
        """Write a setting; returns the line sent (errors name it)."""
        line = setting.text(*args)
        self.link.write_line(line)
        return line

    def ask(self, query: Query[T], *args: object, timeout_s: float | None = None) -> T:
        """One query; a reply `parse` rejects is a transient DeviceError naming command and reply.
        `timeout_s` replaces the link's timeout for this reply (a slow measurement)."""
        line = query.text(*args)
        reply = self.link.query(line, timeout_s)
        self.check_refusal(line, reply)
        try:
            return query.parse(reply)
        except UnexpectedReply as exc:
            message = exc.message.format(command=line, reply=reply)
        except ValueError:
            message = f"garbled reply to {line!r}: {reply!r}"
        raise DeviceError(self.name, message, transient=True)

    def check_refusal(self, line: str, reply: str) -> None:
        """Raise the instrument's own error reply (e.g. the P-9710's `?x`) as a persistent DeviceError;
        the default: the instrument has none (a refusal then shows elsewhere, e.g. an error queue)."""

    # -- under the retry policy -------------------------------------------------------------------
    def query(self, query: Query[T], *args: object) -> T:
        """One query under the retry policy, reconnecting before each retry."""
        return self.retrying(query.text(*args), lambda: self.ask(query, *args))


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
