"""A campaign's runs on one rig-time axis (issue 35): rig time continues across a resume, the manifest lists the
runs with their warm-ups and its total is their sum; old datasets (no `runs`) are placed run after run."""

from __future__ import annotations

import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from rig.acquisition.engine import Runner
from rig.config.campaign import Lamp, parse_campaign
from rig.config.rigfile import RigConfig
from rig.data.campaign_runs import RunRecorder, reached_s, read_events, runs_of
from rig.data.dataset_reader import read_brdf_table
from rig.data.dataset_writer import DatasetWriter
from rig.planning.estimate import WarmupEstimate
from rig.planning.plan import build_plan
from rig.simulators.rig import SimulatedRig

CAMPAIGN = parse_campaign({
    "name": "runs", "sample": {"id": "S", "simulated_brdf": {"model": "lambert", "params": {"kd": 0.5}}},
    "incidence": [{"phi": 0, "theta": [0, 40]}],
    "viewing": [{"centred_on": "normal", "theta": [15, 35], "phi": [0, 90, 180, 270]}],
    "lamp": {"warmup_min_s": 60, "warmup_check_s": 30}})
KNOWN = WarmupEstimate(100.0, "a test's")


def measure(folder: Path, stop_after: int | None = None) -> str:
    """One run of CAMPAIGN into `folder` (new, or resumed as `rig run --resume` leaves it), stopped after
    `stop_after` points."""
    rig = RigConfig()
    if folder.exists():
        writer = DatasetWriter.reopen(folder)
        writer.event("resume", previous_status=writer.manifest["status"])
        writer.update_manifest(status="running", resumes=[*writer.manifest.get("resumes", []),
                                                          {"previous_status": writer.manifest["status"]}])
        done = read_brdf_table(folder).rows
    else:
        writer, done = DatasetWriter(folder, {}), []
    with SimulatedRig(rig, "lambert", {"kd": 0.5}) as sim:
        runner = Runner(CAMPAIGN, build_plan(CAMPAIGN, rig), sim.devices, writer, rig, done_rows=done, warmup=KNOWN,
                        progress=lambda p: runner.request_stop("test") if stop_after and p.done >= stop_after else None)
        status = runner.run()
    writer.close()
    return status


def test_rig_time_continues_across_a_resume_and_the_manifest_sums_the_runs(tmp_path):
    folder = tmp_path / "ds"
    assert measure(folder, stop_after=5) == "interrupted"
    first_total = json.loads((folder / "dataset.json").read_text())["rig_time_s"]
    assert measure(folder) == "complete"
    times = [float(r["rig_time_s"]) for r in read_brdf_table(folder).rows]
    assert len(times) == 16 and all(a < b for a, b in zip(times, times[1:]))       # monotonic in measuring order
    manifest = json.loads((folder / "dataset.json").read_text())
    runs = manifest["runs"]
    assert [r["status"] for r in runs] == ["interrupted", "complete"] and runs[1]["resumed"]
    assert runs[1]["rig_time_offset_s"] == pytest.approx(first_total)
    assert manifest["rig_time_s"] == pytest.approx(sum(r["rig_time_s"] for r in runs))
    assert all(len(r["warmups"]) == 1 and r["expected_warmup"]["seconds"] == 100.0 for r in runs)
    placed = runs_of(manifest, read_events(folder))
    assert [len(r.warmups) for r in placed] == [1, 1]
    assert placed[1].offset_s == pytest.approx(placed[0].end_s, abs=1e-6)
    assert placed[0].illuminance[-1][0] < placed[1].illuminance[0][0]          # each run's readings on its side


def old_events() -> list[dict]:
    """Two runs written before rig time continued: the second restarts at 0."""
    run = [{"event": "lamp_on", "rig_time_s": 5.0, "current_a": 4.2, "voltage_v": 11.6},
           {"event": "warmup_stable", "rig_time_s": 65.0, "warmup_s": 60.0, "change_rel": 0.001, "lamp_voltage_v": 12},
           {"event": "illuminance", "rig_time_s": 70.0, "illuminance_normal_lx": 5000.0, "u_lx": 4.0},
           {"event": "safe_state", "rig_time_s": 100.0}]
    return [*run, {"event": "resume", "previous_status": "interrupted"}, {"event": "devices"}, *run]


def test_an_old_dataset_reads_run_after_run_and_a_resume_of_it_continues_from_its_total(tmp_path):
    manifest = {"status": "interrupted", "resumes": [{"previous_status": "interrupted"}]}
    runs = runs_of(manifest, old_events())
    assert [(r.offset_s, r.end_s) for r in runs] == [(0.0, 100.0), (100.0, 200.0)]
    assert runs[1].illuminance == [(170.0, 5000.0, 4.0)] and runs[1].warmups[0].end_s == 165.0
    assert reached_s(manifest, old_events(), rows=[{"rig_time_s": "99"}]) == 200.0
    writer = DatasetWriter(tmp_path / "old", manifest)
    for event in old_events():
        fields = dict(event)
        writer.event(fields.pop("event"), **fields)
    recorder = RunRecorder(writer, [], Lamp(), RigConfig(), KNOWN)
    assert recorder.offset_s == 200.0
    listed = writer.manifest["runs"]
    assert [r.get("rig_time_shift_s") for r in listed] == [0.0, 100.0, None]
    new_runs = runs_of(writer.manifest, read_events(writer.dir))                 # the same places once listed
    assert [(r.offset_s, r.end_s) for r in new_runs] == [(0.0, 100.0), (100.0, 200.0)]
    writer.close()


def test_a_killed_run_is_closed_at_the_rig_time_it_reached(tmp_path):
    writer = DatasetWriter(tmp_path / "ds", {})
    RunRecorder(writer, [], Lamp(), RigConfig(), KNOWN)
    writer.event("illuminance", rig_time_s=321.0, illuminance_normal_lx=5000.0)        # then the process died
    writer.update_manifest(resumes=[{"previous_status": "running"}])
    writer.event("resume", previous_status="running")
    recorder = RunRecorder(writer, [{"rig_time_s": "330.5"}], Lamp(), RigConfig(), KNOWN)
    first, second = writer.manifest["runs"]
    assert first["status"] == "abandoned" and first["rig_time_s"] == pytest.approx(330.5)
    assert recorder.offset_s == pytest.approx(330.5) == second["rig_time_offset_s"]
    writer.close()


def test_a_resume_expects_the_warm_up_its_dataset_had(tmp_path):
    writer = DatasetWriter(tmp_path / "ds", {})
    first = RunRecorder(writer, [], Lamp(), RigConfig())
    assert "simulated lamp's model" in first.expected.source
    first.warmed(SimpleNamespace(lamp_voltage_v=12.0, warmup_s=700.0, stable=True, change_rel=0.001), 705.0)
    writer.update_manifest(runs=first.ended("interrupted", 900.0), resumes=[{"previous_status": "interrupted"}])
    second = RunRecorder(writer, [], Lamp(), RigConfig())
    assert second.expected.seconds == 720.0 and "in this dataset" in second.expected.source   # at a check: 300+7×60
    writer.close()


def test_a_hand_edited_runs_list_does_not_stop_a_resume(tmp_path):
    writer = DatasetWriter(tmp_path / "ds", {"runs": ["junk", {"warmups": {"not": "a list"}, "status": "running"}],
                                             "resumes": "not a list"})
    recorder = RunRecorder(writer, [], Lamp(), RigConfig(), KNOWN)
    assert recorder.offset_s == 0.0 and writer.manifest["runs"][-1]["run"] == 1
    writer.close()
