"""The SM15K's command syntax, as the manual "Ethernet & Sequencer Programming SM15K" (rev. July 2021)
describes it, for the protocol peer (rig.simulators.delta_sm_peer): keywords, parameters, the error queue.

Headers are separated by `:`, in any case, each keyword in its long form, its short form (the capitals) or
anything in between (`CURR`); `[STAtus]` nodes may be left out (§4.1, §4.5). Literal brackets are not part of
the syntax: `SYSTem:RSD[:STAtus]?` is an undefined header. The manual publishes no error list: the codes here
are SCPI's, and a client must not rely on them.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable, Sequence

#: The error queue holds this many entries; more are ignored (§5.6.7).
ERROR_QUEUE_SIZE = 10
NO_ERROR = "0,None"
BOOLEAN = {"ON": True, "OFF": False, "1": True, "0": False}
REMOTE_LOCAL = {"REMote": True, "LOCal": False}

#: A setting: the parameter text → None, or a reply (`WATchdog SET?` is a query written as a parameter).
Setter = Callable[[str], str | None]
Getter = Callable[[], str]
#: (keywords, setter(parameter), getter() -> reply); None where that form does not exist.
Command = tuple[tuple[str, ...], Setter | None, Getter | None]


class ScpiError(Exception):
    """A command the supply refuses: queued as `code,message`."""

    def __init__(self, code: int, message: str):
        super().__init__(f"{code},{message}")
        self.code = code
        self.message = message


def keyword_matches(token: str, mnemonic: str) -> bool:
    """`token` names `mnemonic` (e.g. `VOLtage`): at least its capitals, at most its long form, any case."""
    short = "".join(c for c in mnemonic if not c.islower())
    token, long = token.upper(), mnemonic.upper()
    return long.startswith(token) and token.startswith(short)


def header_matches(tokens: Sequence[str], mnemonics: tuple[str, ...]) -> bool:
    """The header names the command, with or without its optional (`[...]`) last node."""
    forms = [mnemonics]
    if mnemonics[-1].startswith("["):
        forms = [mnemonics[:-1], (*mnemonics[:-1], mnemonics[-1].strip("[]"))]
    return any(len(tokens) == len(form) and all(map(keyword_matches, tokens, form)) for form in forms)


def required(param: str) -> str:
    if not param:
        raise ScpiError(-109, "Missing parameter")
    return param


def number(param: str, low: float = -math.inf, high: float = math.inf) -> float:
    """A finite <NR2> within [low, high]."""
    try:
        value = float(required(param))
    except ValueError:
        raise ScpiError(-104, "Data type error") from None
    if not math.isfinite(value):
        raise ScpiError(-104, "Data type error")
    if not low <= value <= high:
        raise ScpiError(-222, "Data out of range")
    return value


def integer(param: str, low: int, high: int) -> int:
    """An <NR1> within [low, high]."""
    try:
        value = int(required(param))
    except ValueError:
        raise ScpiError(-104, "Data type error") from None
    if not low <= value <= high:
        raise ScpiError(-222, "Data out of range")
    return value


def choice(param: str, choices: dict[str, bool]) -> bool:
    required(param)
    for mnemonic, value in choices.items():
        if keyword_matches(param, mnemonic):
            return value
    raise ScpiError(-224, "Illegal parameter value")


def arguments(param: str, count: int) -> list[str]:
    """Exactly `count` comma-separated parameters."""
    parts = [p.strip() for p in required(param).split(",")]
    if len(parts) != count:
        raise ScpiError(-109 if len(parts) < count else -108,
                        "Missing parameter" if len(parts) < count else "Parameter not allowed")
    return parts


def scientific(value: float) -> str:
    """Scientific notation with 15 decimals, as the manual's step sizes (`1.055924221873283e-03`)."""
    return f"{value:.15e}"


class ErrorQueue:
    """At most ERROR_QUEUE_SIZE entries, oldest first; when it is full, new entries are ignored (§5.6.7).
    The warning queue (§5.6.8) is read the same way."""

    def __init__(self) -> None:
        self._entries: deque[tuple[int, str]] = deque()

    def push(self, code: int, message: str) -> None:
        if len(self._entries) < ERROR_QUEUE_SIZE:
            self._entries.append((code, message))

    def pop(self) -> str:
        if not self._entries:
            return NO_ERROR
        code, message = self._entries.popleft()
        return f"{code},{message}"

    def clear(self) -> None:
        self._entries.clear()

    def __len__(self) -> int:
        return len(self._entries)
