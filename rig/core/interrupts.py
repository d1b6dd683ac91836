"""SIGTERM and SIGHUP end a command the way Ctrl+C does, so that one clean-up path serves all three.

A command that writes files (`rig plot`, `rig export`, `rig report`, ...) cleans up on KeyboardInterrupt, the
exception Python raises for SIGINT: `removed_on_failure` removes the new output, `new_file` its temporary file,
a temporary folder its contents, a child process is killed (rig.data.radiance.run_tool). Python's own
SIGTERM and SIGHUP end the process at once, skipping all of that (a half-written output that makes the rerun
refuse, a temporary folder, children still writing), so `interruptible` raises `Interrupted`, a
KeyboardInterrupt, for them too. `rig run` stops differently (it parks the axes and switches the lamp off
first: rig.acquisition.execute.stop_on_signals) and does not use this.
"""

from __future__ import annotations

import functools
import signal
import sys
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import TypeVar

#: The signals that end a writing command; SIGHUP is what a closed terminal or ssh session sends.
ENDING_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)

A = TypeVar("A")


class Interrupted(KeyboardInterrupt):
    """The command was ended by `signum`; a KeyboardInterrupt, so every `except KeyboardInterrupt` and every
    clean-up that handles Ctrl+C handles it the same way."""

    def __init__(self, signum: int):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


class _Held:
    """Signals held by `held_signals` (main thread only, like the handlers)."""

    depth = 0
    pending: int | None = None


@contextmanager
def held_signals() -> Iterator[None]:
    """An ending signal that lands in the block is raised when the block is done, not inside it: for a step
    whose result the clean-up needs, such as a child process started and its handle not yet kept."""
    _Held.depth += 1
    try:
        yield
    finally:
        _Held.depth -= 1
    if _Held.depth == 0 and _Held.pending is not None:
        signum, _Held.pending = _Held.pending, None
        raise Interrupted(signum)


@contextmanager
def signals_interrupt() -> Iterator[None]:
    """In the block, the first of `ENDING_SIGNALS` raises `Interrupted` (at the end of `held_signals` if it
    lands in one); later ones are ignored, so that they cannot cut the clean-up short. Main thread only
    (elsewhere Python cannot install handlers): a no-op there."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    raised: list[int] = []

    def handler(signum: int, frame: object) -> None:
        if not raised:
            raised.append(signum)
            if _Held.depth:
                _Held.pending = signum
            else:
                raise Interrupted(signum)

    saved = {sig: signal.signal(sig, handler) for sig in ENDING_SIGNALS}
    try:
        yield
    finally:
        for sig, previous in saved.items():
            signal.signal(sig, previous)


def interruptible(command: Callable[[A], int]) -> Callable[[A], int]:
    """A `rig` subcommand that SIGINT, SIGTERM and SIGHUP end alike: its clean-up runs, then one line on stderr
    and the shell's code for that signal (128 + its number: 130, 143, 129)."""
    @functools.wraps(command)
    def run(args: A) -> int:
        try:
            with signals_interrupt():
                return command(args)
        except KeyboardInterrupt as exc:
            signum = exc.signum if isinstance(exc, Interrupted) else signal.SIGINT
            print(f"rig: stopped by {signal.Signals(signum).name}; nothing unfinished was left behind",
                  file=sys.stderr)
            return 128 + int(signum)
    return run
