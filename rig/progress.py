"""A one-line progress bar with ETA for terminal runs (plain lines when not a terminal)."""

from __future__ import annotations

import sys
import time
from typing import TextIO

from rig.runner import Progress


def format_duration(seconds: float) -> str:
    seconds = max(0, int(round(seconds)))
    h, rem = divmod(seconds, 3600)
    m, s = divmod(rem, 60)
    return f"{h}:{m:02d}:{s:02d}"


class ProgressBar:
    """Callable for Runner(progress=...): redraws at most every `min_interval_s`."""

    def __init__(self, stream: TextIO = sys.stderr, width: int = 30, min_interval_s: float = 0.1):
        self.stream = stream
        self.width = width
        self.min_interval_s = min_interval_s
        self.tty = stream.isatty()
        self.start = time.monotonic()
        self._last_draw = 0.0
        self._last_tenth = -1

    def __call__(self, p: Progress) -> None:
        now = time.monotonic()
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
        wall = now - self.start
        eta_wall = wall / p.done * (p.total - p.done) if p.done else float("nan")
        eta_rig = p.rig_time_s / p.done * (p.total - p.done) if p.done else float("nan")
        filled = int(round(frac * self.width))
        bar = "#" * filled + "." * (self.width - filled)
        eta = (f"ETA {format_duration(eta_wall)} wall, {format_duration(eta_rig)} rig"
               if p.done else "ETA --")
        line = (f"[{bar}] {p.done}/{p.total} {frac:4.0%}  rig {format_duration(p.rig_time_s)}  {eta}"
                f"  {p.message}")
        if self.tty:
            self.stream.write("\r" + line[:160].ljust(160))
            if finished:
                self.stream.write("\n")
        else:
            self.stream.write(line + "\n")
        self.stream.flush()
