"""A one-line progress bar with ETA for terminal runs (plain lines when not a terminal).

On a terminal every redraw returns to the start of the line, writes the line and clears what is
left of the previous one (no padding: a ^C typed at the end of the line must not wrap); the line
fits in the terminal's width (asked at each redraw, so a resized window is followed): a line that
wrapped could not be redrawn in place, and the bar would scroll. A narrow terminal loses whole fields
(the bar, the rig-time ETA, the rig time, the message's last words), never part of one. Whatever is
said after the run (`end_progress_lines` first) starts on a line of its own.
"""

from __future__ import annotations

import os
import shutil
import sys
import time
import weakref
from typing import TextIO

from rig.core.values import Progress

#: Widest bar (characters between the brackets); narrower terminals get a shorter one, or none.
BAR_WIDTH = 30
#: Narrowest bar worth drawing; with less room the line is the text alone.
MIN_BAR_WIDTH = 5
#: Room kept beside the bar for the counts and both ETAs ("1865/1865 100%  rig 0:54:17  ETA 0:00:20 wall,
#: 0:54:17 rig" is 58 characters); the message gets what is left.
TEXT_ROOM = 58
#: Characters of a message worth dropping fields for (a warm-up's elapsed time and rest).
MESSAGE_ROOM = 30
#: What may end a word where a message is cut.
WORD_ENDS = " ,;:)"
#: Clears from the cursor to the end of the line (ANSI EL): what a shorter redraw leaves of the longer one.
CLEAR_TO_END = "\x1b[K"
#: Bars whose line is drawn and not yet ended (`end_progress_lines`).
_OPEN: weakref.WeakSet[ProgressBar] = weakref.WeakSet()
#: What the first Ctrl+C does, by the run's stage (rig.acquisition.eta.Eta.stage); None: not started yet.
STOP_WORDS = {None: "stopping before the run starts: nothing is switched on",
              "starting": "stopping before the warm-up: lamp off",
              "warm-up": "stopping the warm-up: lamp off, park",
              "measuring": "stopping after the point in flight: park, lamp off",
              "between": "stopping: park, lamp off"}


def stop_words(stage: str | None) -> str:
    """What the terminal says when the first Ctrl+C arrives in `stage` (the words of rig.acquisition.execute)."""
    return f"{STOP_WORDS.get(stage, STOP_WORDS['between'])} (Ctrl+C again: stop the axes now)"


def end_progress_lines() -> None:
    """End every progress line still open, so that the next message starts on its own line."""
    for bar in list(_OPEN):
        bar.end_line()


def format_duration(seconds: float) -> str:
    seconds = max(0, int(round(seconds)))
    h, rem = divmod(seconds, 3600)
    m, s = divmod(rem, 60)
    return f"{h}:{m:02d}:{s:02d}"


def terminal_columns(stream: TextIO) -> int:
    """Width of the terminal `stream` writes to; else shutil's answer (COLUMNS, stdout's terminal, 80)."""
    try:
        columns = os.get_terminal_size(stream.fileno()).columns
    except (AttributeError, OSError, ValueError):     # no file descriptor, or not a terminal
        columns = 0
    return columns if columns > 0 else shutil.get_terminal_size().columns


class ProgressBar:
    """Callable for Runner(progress=...): redraws at most every `min_interval_s`.

    `columns`: a fixed width (tests); None asks the terminal at every redraw. The wall-time
    ETA converts the runner's rig-time ETA at the wall seconds per rig second seen since the
    first point (the simulated rig runs many rig seconds per wall second, hardware one).
    """

    def __init__(self, stream: TextIO = sys.stderr, min_interval_s: float = 0.1, columns: int | None = None):
        self.stream = stream
        self.min_interval_s = min_interval_s
        self.columns = columns
        self.tty = stream.isatty()
        self._last_draw = 0.0
        self._last_tenth = -1
        self._first_done: int | None = None                     # points done at the first report (a resume)
        self._rate_origin: tuple[float, float] | None = None    # (wall, rig time) at the first point measured

    def _etas(self, p: Progress, now: float) -> tuple[str, str]:
        """The ETA field in full (wall and rig time) and short (the wall time, else the rig time)."""
        if p.eta_rig_s is None:
            return "ETA --", "ETA --"
        rig = f"{format_duration(p.eta_rig_s)} rig"
        if self._rate_origin is None or p.rig_time_s <= self._rate_origin[1]:
            return f"ETA {rig}", f"ETA {rig}"
        wall0, rig0 = self._rate_origin
        wall = format_duration(p.eta_rig_s * (now - wall0) / (p.rig_time_s - rig0))
        return f"ETA {wall} wall, {rig}", f"ETA {wall}"

    def _line(self, p: Progress, frac: float, now: float, columns: int | None) -> str:
        """The progress line; with `columns`, at most columns - 1 characters (the last column would wrap).

        The bar's width depends on the terminal's alone, so it does not jump between redraws; a narrow
        terminal shortens it (down to MIN_BAR_WIDTH, then none). Then whole fields go, the least needed
        first, as far as the message then fits whole (or MESSAGE_ROOM of it): the rig-time half of the ETA,
        the rig time (the ETA only where nothing else fits); the message keeps the words that fit.
        """
        width = BAR_WIDTH if columns is None else min(BAR_WIDTH, columns - 1 - len("[] ") - TEXT_ROOM)
        bar = f"[{'#' * round(frac * width)}{'.' * (width - round(frac * width))}] " if width >= MIN_BAR_WIDTH else ""
        counts, rig = f"{p.done}/{p.total} {frac:4.0%}", f"rig {format_duration(p.rig_time_s)}"
        full, short = self._etas(p, now)
        if columns is None:
            return "  ".join(f for f in (bar + counts, rig, full, p.message) if f)
        room = columns - 1 - len(bar)
        choices = [f for f in ((counts, rig, full), (counts, rig, short), (counts, short), (counts,))
                   if len("  ".join(f)) <= room]
        with_eta = choices[:-1] if len(choices) > 1 else []      # the ETA goes for no message
        whole = [f for f in with_eta if len("  ".join(f)) + 2 + len(p.message) <= room]    # the message uncut
        roomy = [f for f in with_eta if len("  ".join(f)) + 2 + MESSAGE_ROOM <= room]     # or enough of it
        line = "  ".join(next(iter(whole or roomy or choices), ()))
        words = _words_within(p.message, room - len(line) - 2) if line else ""
        return (bar + "  ".join(f for f in (line, words) if f))[:max(columns - 1, 0)]

    def end_line(self) -> None:
        """End the drawn line (a newline) if one is open: what follows starts on its own line."""
        if self in _OPEN:
            _OPEN.discard(self)
            self.stream.write("\n")
            self.stream.flush()

    def __call__(self, p: Progress) -> None:
        now = time.monotonic()
        if self._first_done is None:
            self._first_done = p.done
        if self._rate_origin is None and p.done > self._first_done:
            self._rate_origin = (now, p.rig_time_s)
        finished = p.total and p.done >= p.total
        if self.tty and not finished and now - self._last_draw < self.min_interval_s:
            return
        frac = p.done / p.total if p.total else 1.0
        if not self.tty:                      # logs and CI: one line per 10 %
            tenth = int(frac * 10)
            if tenth == self._last_tenth:
                return
            self._last_tenth = tenth
        self._last_draw = now
        if self.tty:
            columns = self.columns or terminal_columns(self.stream)
            self.stream.write("\r" + self._line(p, frac, now, columns) + CLEAR_TO_END)
            _OPEN.add(self)
            if finished:
                self.end_line()
        else:
            self.stream.write(self._line(p, frac, now, None) + "\n")
        self.stream.flush()


def _words_within(message: str, room: int) -> str:
    """`message` if it fits in `room` characters, else its first words that fit followed by "…", else ""."""
    if len(message) <= room:
        return message
    if room < 2:
        return ""
    cut = message[:room - 1]                          # a column for the "…"
    if message[room - 1] not in WORD_ENDS:            # the cut falls inside a word: leave that word out
        cut = cut.rsplit(" ", 1)[0] if " " in cut else ""
    cut = cut.rstrip(WORD_ENDS)
    return f"{cut}…" if cut else ""
