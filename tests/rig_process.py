"""`rig` as a real process, for the tests that signal, kill or race it and watch its dataset folder.

The bound of `wait_until` is a hang guard (a run that never gets there fails the test instead
of blocking the suite), not a speed assertion: its bound is far beyond any machine's run time.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest

#: Longest wall time a test waits for a `rig` process to reach a state before it calls it hung.
HANG_S = 120.0


def start_rig(*args: str, env: dict[str, str] | None = None, **popen) -> subprocess.Popen:
    """`python -m rig.cli.main ARGS` with text pipes (unless `popen` redirects them); `env` is added to
    this process's environment."""
    pipes = {"stdout": subprocess.PIPE, "stderr": subprocess.PIPE, **popen}
    return subprocess.Popen([sys.executable, "-m", "rig.cli.main", *args], text=True,
                            env={**os.environ, **(env or {})}, **pipes)


def events_text(folder: Path) -> str:
    """events.jsonl as it is now ("" before the run has created it)."""
    try:
        return (folder / "events.jsonl").read_text()
    except FileNotFoundError:
        return ""


def pending_points(folder: Path) -> int:
    """Points measured so far: each is written ahead as `point_pending` before it reaches brdf.csv."""
    return events_text(folder).count('"point_pending"')


#: Pause between two looks at the folder.
POLL_S = 0.002


def wait_until(ready: Callable[[], bool], proc: subprocess.Popen, what: str, timeout_s: float = HANG_S) -> None:
    """Poll `ready()` until it holds; fail the test if `proc` ends first or hangs.

    The guard counts polls rather than reading a clock: on a loaded machine it only gets longer.
    """
    for _ in range(int(timeout_s / POLL_S)):
        if ready():
            return
        if proc.poll() is not None:
            pytest.fail(f"rig ended (exit {proc.returncode}) before {what}: {proc.stderr.read()}")
        time.sleep(POLL_S)
    proc.kill()
    pytest.fail(f"rig did not reach {what} in {timeout_s:.0f} s of polling: hung")
