"""Adaptive sampling (campaign key `sampling`, mode adaptive) on the simulated rig: batches logged before they are
measured, the budget kept, and a run killed mid-adaptation resumes to the same points as an uninterrupted one."""

import json
import signal
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from repo_paths import TEST_CAMPAIGNS
from rig.bench.sampling import measuring_time_s
from rig.cli.main import main
from rig.config.campaign import load_campaign
from rig.config.rigfile import simulated_rig
from rig.data.dataset_reader import load
from rig.planning.candidates import candidate_plan
from rig_process import start_rig, wait_until

CAMPAIGN = TEST_CAMPAIGNS / "e2e-adaptive.yaml"


def events(folder: Path) -> list[dict]:
    return [json.loads(line) for line in (folder / "events.jsonl").read_text().splitlines()]


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("adaptive") / "ds"
    assert main(["run", str(CAMPAIGN), "--out", str(out), "--quiet"]) == 0
    return out


def test_batches_are_logged_before_they_are_measured_and_the_budget_holds(uninterrupted):
    campaign = load_campaign(CAMPAIGN)
    ev = events(uninterrupted)
    ds = load(uninterrupted)
    batches = [e for e in ev if e["event"] == "adaptive_batch"]
    assert len(batches) >= 3
    first_row = {e["row"]["point_id"]: k for k, e in enumerate(ev) if e["event"] == "point_pending"}
    position = {id(e): k for k, e in enumerate(ev)}
    for b in batches:              # every point of a batch is measured, and after its batch was logged
        assert all(first_row[pid] > position[id(b)] for pid in b["points"])
        assert len(b["points"]) <= campaign.sampling.batch_points and b["gain"] > 0 and b["why"]
    done = [e for e in ev if e["event"] == "sampling_done"]
    assert len(done) == 1 and done[0]["reason"].startswith("budget reached")
    assert done[0]["planned_rig_time_s"] <= campaign.sampling.budget_rig_time_s
    # the planned rig time is an honest estimate of the real one (moves dominate; readings and captures add some)
    assert 0.9 <= measuring_time_s(uninterrupted) / done[0]["planned_rig_time_s"] <= 1.3
    # every row is a candidate, measured once; the mandatory pair is among them
    candidates = {p.point_id: p for p in candidate_plan(campaign, simulated_rig()).points}
    assert set(ds.point_id) <= set(candidates) and len(set(ds.point_id)) == len(ds)
    assert any(abs(candidates[p].theta_i_deg - 30) < 1e-9 and abs(candidates[p].theta_o_deg - 30) < 1e-9
               for p in ds.point_id)
    # batches went to other incidences than the first pass's two (0° and 85°)
    assert len(np.unique(np.round(ds["theta_i_deg"]))) >= 4


def test_a_run_killed_mid_adaptation_resumes_to_the_same_points(uninterrupted, tmp_path):
    out = tmp_path / "ds"
    proc = start_rig("run", str(CAMPAIGN), "--out", str(out), "--quiet")
    text = lambda: (out / "events.jsonl").read_text() if (out / "events.jsonl").exists() else ""  # noqa: E731

    def inside_second_batch() -> bool:
        t = text()
        return t.count('"adaptive_batch"') >= 2 and t.split('"adaptive_batch"')[2].count('"point_pending"') >= 3

    wait_until(inside_second_batch, proc, "the third point of the second adaptive batch")
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=60)
    assert '"sampling_done"' not in text()
    resumed = subprocess.run([sys.executable, "-m", "rig.cli.main", "run", "--resume", str(out), "--quiet"],
                             capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    assert sorted(load(out).point_id) == sorted(load(uninterrupted).point_id)
    ev = events(out)
    numbers = [e["batch"] for e in ev if e["event"] == "adaptive_batch"]
    assert numbers == list(range(1, len(numbers) + 1))          # the batch in flight was finished, not re-chosen
    assert [e["event"] for e in ev].count("sampling_done") == 1
