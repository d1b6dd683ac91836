"""`rig bench sampling` on a dask scheduler and worker started as separate processes on loopback (rig.bench):
the study's results are gathered from the worker, and a task that fails is reported with its draw and seed."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import threading
from collections.abc import Iterator

import pytest

from repo_paths import ROOT, TEST_CAMPAIGNS

distributed = pytest.importorskip("distributed")

from rig.bench import sampling  # noqa: E402
from rig.bench.draws import Draw  # noqa: E402
from rig.bench.sampling_report import distribution  # noqa: E402
from rig.cli.main import main  # noqa: E402
from rig.config.campaign import load_campaign  # noqa: E402

CAMPAIGN = TEST_CAMPAIGNS / "sampling-tiny.yaml"


def _spawn(*args: str) -> subprocess.Popen:
    """A dask CLI in a session of its own (so that it and its children are killed together), quiet, importing rig
    from this checkout (its worker processes too)."""
    path = os.pathsep.join(p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p)
    return subprocess.Popen([sys.executable, "-m", *args], cwd=ROOT, start_new_session=True,
                            env={**os.environ, "PYTHONPATH": path},
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)


def _logged(proc: subprocess.Popen, marker: str) -> str:
    """The rest of the first log line (stderr) of `proc` holding `marker`, read as the process writes it: no clock,
    and a process that exits first ends the wait with its log. Its later lines are drained, so that it never
    blocks on a full pipe."""
    assert proc.stderr is not None
    seen = []
    for line in proc.stderr:
        seen.append(line)
        if marker in line:
            threading.Thread(target=proc.stderr.read, daemon=True).start()
            return line.split(marker, 1)[1].strip()
    raise AssertionError(f"{proc.args[2]} exited ({proc.wait()}) before logging {marker!r}:\n{''.join(seen)}")


def _stop(proc: subprocess.Popen) -> None:
    for sig in (signal.SIGTERM, signal.SIGKILL):
        try:
            os.killpg(proc.pid, sig)
        except ProcessLookupError:
            return
        try:
            proc.wait(timeout=10)
            return
        except subprocess.TimeoutExpired:
            continue


@pytest.fixture(scope="module")
def scheduler() -> Iterator[str]:
    """The address of a scheduler (`dask scheduler`) with one single-threaded worker (`dask worker`)."""
    procs = [_spawn("distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                    "--dashboard-address", "127.0.0.1:0")]
    try:
        address = _logged(procs[0], "Scheduler at:")
        procs.append(_spawn("distributed.cli.dask_worker", address, "--nworkers", "1", "--nthreads", "1",
                            "--no-dashboard", "--dashboard-address", "127.0.0.1:0", "--host", "127.0.0.1"))
        assert _logged(procs[1], "Registered to:") == address
        yield address
    finally:
        for proc in reversed(procs):
            _stop(proc)


def test_the_study_runs_through_a_scheduler_address(scheduler, tmp_path, capsys):
    out = tmp_path / "study"
    code = main(["bench", "sampling", str(CAMPAIGN), "--draws", "1", "--families", "lambert", "--budgets", "0.5",
                 "--scheduler", scheduler.removeprefix("tcp://"), "--out", str(out)])
    text = capsys.readouterr().out
    assert code == 0, text
    assert f"1 dask workers at {scheduler}" in text
    saved = json.loads((out / "sampling.json").read_text())
    assert not saved["failures"]
    strategies = sorted(r["strategy"] for r in saved["results"])
    assert strategies == ["adaptive ×0.5", "table", "table, optimised"]
    table = next(r for r in saved["results"] if r["strategy"] == "table")
    adaptive = next(r for r in saved["results"] if r["fraction"] == 0.5)
    assert adaptive["points"] < table["points"] and 0.3 < adaptive["rig_time_s"] / table["rig_time_s"] < 0.7
    assert table["errors"]["all_p95"] > 0 and (out / "sampling.png").stat().st_size > 0
    assert "table reached by" in text or "NOT reached" in text


def test_a_failed_task_is_reported_with_its_draw_and_seed(scheduler):
    good, bad = Draw(0, 11, "lambert", {"kd": 0.5}), Draw(1, 11, "no_such_family", {"kd": 0.5})
    with distributed.Client(scheduler) as client:
        results, failures = sampling.study(client, load_campaign(CAMPAIGN), [good, bad], [0.5])
    assert sorted(r.strategy for r in results) == ["adaptive ×0.5", "table", "table, optimised"]
    assert len(failures) == 1
    failure = failures[0]
    assert failure.meta == {"draw": 1, "seed": 11, "family": "no_such_family", "strategy": "table"}
    assert "draw 1 (seed 11" in failure.label and "no_such_family" in failure.error
    assert "1 task(s) FAILED" in distribution(results, failures) and "draw 1 (seed 11" in distribution(
        results, failures)
