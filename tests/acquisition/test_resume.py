"""Interrupt, kill and resume on the simulated rig: same point ids as an uninterrupted run, no
duplicates, every file readable, the lamp off after every exit.

The campaign runs as a real `rig run` process; signals are sent once its brdf.csv (or the
write-ahead log) holds a random number of points.
"""

import csv
import json
import random
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from repo_paths import E2E_CAMPAIGN as CAMPAIGN
from rig.config.campaign import load_campaign
from rig.config.rigfile import RigConfig
from rig.planning.plan import build_plan
from rig_process import pending_points, start_rig, wait_until


def signal_after(proc, folder: Path, n_points: int, sig: int) -> None:
    wait_until(lambda: pending_points(folder) >= n_points, proc, f"{n_points} points")
    proc.send_signal(sig)


def ids(folder: Path) -> list[str]:
    with open(folder / "brdf.csv", newline="") as fh:
        return [r["point_id"] for r in csv.DictReader(fh)]


def manifest(folder: Path) -> dict:
    return json.loads((folder / "dataset.json").read_text())


def events(folder: Path) -> list[dict]:
    return [json.loads(line) for line in (folder / "events.jsonl").read_text().splitlines()]


@pytest.fixture(scope="module")
def planned_ids():
    return sorted(p.point_id for p in build_plan(load_campaign(CAMPAIGN), RigConfig()).points)


def resume_to_completion(folder: Path, *extra) -> subprocess.CompletedProcess:
    proc = subprocess.run([sys.executable, "-m", "rig.cli.main", "run", "--resume", str(folder), "--quiet", *extra],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    return proc


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM, signal.SIGINT])
def test_interrupt_then_resume_gives_the_planned_points_once(tmp_path, planned_ids, sig):
    out = tmp_path / "ds"
    n = random.Random(int(sig) * 7919).randint(3, 80)
    proc = start_rig("run", str(CAMPAIGN), "--out", str(out), "--quiet")
    signal_after(proc, out, n, sig)
    code = proc.wait(timeout=60)
    before = ids(out)
    assert len(before) == len(set(before))
    if sig == signal.SIGKILL:
        assert code == -signal.SIGKILL
        assert manifest(out)["status"] == "running"          # nobody could say otherwise
    else:
        assert code == 130, proc.stderr.read()
        m = manifest(out)
        assert m["status"] == "interrupted" and m["counts"]["measured"] == len(before)
        ev = events(out)
        assert ev[-1]["event"] == "safe_state" and ev[-1]["lamp_off"]
        if sig == signal.SIGINT:                          # graceful: finished the point, parked
            kinds = [e["event"] for e in ev]
            assert "stop_requested" in kinds and "parked" in kinds
            assert len(before) >= n
    resume_to_completion(out)
    after = ids(out)
    assert sorted(after) == planned_ids                   # same ids as an uninterrupted run, once each
    assert after[:len(before)] == before                  # nothing rewritten
    m = manifest(out)
    assert m["status"] == "complete" and m["counts"]["measured"] == len(planned_ids)
    assert len(m["resumes"]) == 1
    with open(out / "brdf.csv", newline="") as fh:        # every row readable, every number finite
        for row in csv.DictReader(fh):
            assert float(row["brdf_per_sr"]) > 0


def test_kill_mid_write_torn_lines_are_cut(tmp_path, planned_ids):
    out = tmp_path / "ds"
    proc = start_rig("run", str(CAMPAIGN), "--out", str(out), "--quiet")
    signal_after(proc, out, 20, signal.SIGKILL)
    proc.wait(timeout=60)
    with open(out / "brdf.csv", "a") as fh:               # what a kill during a write leaves behind
        fh.write("05-001,4,85.0,0.0,3")
    with open(out / "events.jsonl", "a") as fh:
        fh.write('{"time_utc": "2026-')
    done = resume_to_completion(out)
    assert sorted(ids(out)) == planned_ids
    resume_event = next(e for e in events(out) if e["event"] == "resume")
    assert resume_event["torn_bytes_cut"]["brdf.csv"] > 0 and resume_event["torn_bytes_cut"]["events.jsonl"] > 0
    assert done.returncode == 0


def test_resume_refuses_a_changed_campaign_unless_forced(tmp_path, planned_ids):
    campaign = tmp_path / "c.yaml"
    shutil.copy(CAMPAIGN, campaign)
    out = tmp_path / "ds"
    proc = start_rig("run", str(campaign), "--out", str(out), "--quiet")
    signal_after(proc, out, 10, signal.SIGTERM)
    proc.wait(timeout=60)
    campaign.write_text(campaign.read_text() + "\n# edited\n")
    refused = subprocess.run([sys.executable, "-m", "rig.cli.main", "run", "--resume", str(out)],
                             capture_output=True, text=True, timeout=60)
    assert refused.returncode == 2 and "changed since the run started" in refused.stderr
    assert manifest(out)["status"] == "interrupted"       # refusing touched nothing
    resume_to_completion(out, "--force")
    assert sorted(ids(out)) == planned_ids


def test_resume_of_a_complete_dataset_is_refused(tmp_path):
    out = tmp_path / "ds"
    assert subprocess.run([sys.executable, "-m", "rig.cli.main", "run", str(CAMPAIGN), "--out", str(out), "--quiet"],
                          capture_output=True, timeout=120).returncode == 0
    proc = subprocess.run([sys.executable, "-m", "rig.cli.main", "run", "--resume", str(out)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and "nothing to resume" in proc.stderr


def test_resume_of_a_folder_without_dataset(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "rig.cli.main", "run", "--resume", str(tmp_path)],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and "no readable dataset.json" in proc.stderr
