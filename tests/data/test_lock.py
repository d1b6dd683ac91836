"""One writer per dataset folder (issue 9, defect 5): a second `rig run --resume` while another
process writes the folder is refused with exit 2, naming the holder's pid and host, and changes
nothing; a lock left by a killed process does not block the resume.

The processes are real `rig run` processes; the first one is frozen with SIGSTOP while it holds
the lock, so the folder can be compared byte for byte around the refused attempt.
"""

import csv
import json
import os
import signal
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from repo_paths import E2E_CAMPAIGN as CAMPAIGN
from rig.config.campaign import load_campaign
from rig.config.rigfile import RigConfig
from rig.data.dataset_format import DatasetError
from rig.data.dataset_writer import DatasetWriter
from rig.data.folderlock import LOCK_NAME, FolderLock, FolderLockedError
from rig.planning.plan import build_plan
from rig_process import events_text, pending_points, start_rig, wait_until


def lock_holder(folder: Path) -> str:
    try:
        return (folder / LOCK_NAME).read_text()
    except FileNotFoundError:
        return ""


def snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in sorted(folder.iterdir()) if p.is_file()}


def ids(folder: Path) -> list[str]:
    with open(folder / "brdf.csv", newline="") as fh:
        return [r["point_id"] for r in csv.DictReader(fh)]


@pytest.fixture(scope="module")
def planned_ids():
    return sorted(p.point_id for p in build_plan(load_campaign(CAMPAIGN), RigConfig()).points)


def test_two_resumes_at_once_one_is_refused_and_a_killed_holder_does_not_block(tmp_path, planned_ids):
    out = tmp_path / "ds"
    run = start_rig("run", str(CAMPAIGN), "--out", str(out), "--quiet")
    wait_until(lambda: pending_points(out) >= 10, run, "10 points")
    run.kill()                                            # kill -9: the kernel drops its lock
    assert run.wait(timeout=60) == -signal.SIGKILL
    assert (out / LOCK_NAME).exists()                     # the lock file stays behind ...

    first = start_rig("run", "--resume", str(out), "--quiet")  # ... and does not block this resume
    wait_until(lambda: lock_holder(out).startswith(f"pid {first.pid} "), first, "the resume's lock")
    wait_until(lambda: '"event": "resume"' in events_text(out), first, "the resume event")
    os.kill(first.pid, signal.SIGSTOP)                    # frozen while it holds the lock
    try:
        before = snapshot(out)
        second = subprocess.run([sys.executable, "-m", "rig.cli.main", "run", "--resume", str(out), "--quiet"],
                                capture_output=True, text=True, timeout=60)
        after = snapshot(out)
    finally:
        os.kill(first.pid, signal.SIGCONT)
    assert second.returncode == 2, second.stderr
    message = second.stderr.strip()
    assert message.count("\n") == 0 and "Traceback" not in message
    assert f"pid {first.pid}" in message and f"host {socket.gethostname()}" in message and str(out) in message
    assert after == before                                # the refused process changed nothing

    assert first.wait(timeout=120) == 0, first.stderr.read()
    assert sorted(ids(out)) == planned_ids                # one writer: every planned point exactly once
    manifest = json.loads((out / "dataset.json").read_text())
    assert manifest["status"] == "complete" and len(manifest["resumes"]) == 1
    assert lock_holder(out) == ""                         # released: the holder's name is cleared


def test_a_second_lock_on_the_same_folder_is_refused_until_released(tmp_path):
    first, second = FolderLock(tmp_path), FolderLock(tmp_path)
    first.acquire()
    with pytest.raises(FolderLockedError, match=f"pid {os.getpid()} host {socket.gethostname()}"):
        second.acquire()
    first.release()
    second.acquire()                                      # free again once released
    assert second.held
    second.release()


def test_a_new_folder_taken_by_another_writer_is_refused_and_left_alone(tmp_path):
    out = tmp_path / "ds"
    out.mkdir()
    holder = FolderLock(out)
    holder.acquire()
    try:
        with pytest.raises(DatasetError, match="in use by another rig process"):
            DatasetWriter(out, {"campaign": {"name": "x"}})
        assert sorted(p.name for p in out.iterdir()) == [LOCK_NAME]      # nothing written, nothing removed
    finally:
        holder.release()
    writer = DatasetWriter(out, {"campaign": {"name": "x"}})             # free: the writer takes it
    writer.close()
    assert (out / "dataset.json").exists()
