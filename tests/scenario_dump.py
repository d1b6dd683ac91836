"""A pytest plugin that keeps what the fault and stop scenarios wrote, to compare two versions of rig.

With `RIG_SCENARIO_DUMP=DIR`, after each test it copies the text files the test wrote under its
`tmp_path` (datasets: brdf.csv, dataset.json, events.jsonl, ...) and the test's captured stdout and
stderr (progress lines, final messages) into `DIR/<test id>/`. `benchmarks/scenario_identity.py`
then compares two such folders, apart from ports and times (issue 32: a redesign that changes no
dataset, event stream or progress line). Without the variable it does nothing.
Used as `python -m pytest -p scenario_dump ...` (tests/ is on the path through pytest's rootdir).
"""

from __future__ import annotations

import os
import re
import shutil
from pathlib import Path

import pytest

TEXT_SUFFIXES = {".csv", ".json", ".jsonl", ".txt", ".log", ".yaml"}


def _folder(nodeid: str) -> Path | None:
    root = os.environ.get("RIG_SCENARIO_DUMP")
    if not root:
        return None
    return Path(root) / re.sub(r"[^A-Za-z0-9_.-]+", "_", nodeid)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_call(item: pytest.Item):  # type: ignore[no-untyped-def]
    yield
    target = _folder(item.nodeid)
    tmp = getattr(item, "funcargs", {}).get("tmp_path")
    if target is None or tmp is None:
        return
    for path in sorted(Path(tmp).rglob("*")):
        if path.is_file() and path.suffix in TEXT_SUFFIXES:
            dest = target / "files" / path.relative_to(tmp)
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, dest)


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    target = _folder(report.nodeid)
    if target is None or report.when != "call":
        return
    target.mkdir(parents=True, exist_ok=True)
    (target / "stdout.txt").write_text(report.capstdout)
    (target / "stderr.txt").write_text(report.capstderr)
    (target / "outcome.txt").write_text(report.outcome + "\n")
