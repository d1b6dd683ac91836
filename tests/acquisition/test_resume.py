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
import yaml

from repo_paths import E2E_CAMPAIGN as CAMPAIGN
from repo_paths import ROOT
from rig.acquisition.rig_change import instrument_difference, link_changes
from rig.cli.main import main
from rig.config.campaign import load_campaign
from rig.config.rigfile import RigConfig, simulated_rig
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


# -- `--resume DIR --rig NEW.yaml` (issue 30 item 4): the same instruments, reached where they are now -----------

def _unfinished(tmp_path: Path, rig: RigConfig) -> Path:
    """An interrupted dataset of CAMPAIGN on `rig`, before its first point (what `rig run` writes first)."""
    from rig.acquisition.execute import manifest_for
    from rig.data.dataset_writer import DatasetWriter

    campaign = load_campaign(CAMPAIGN)
    out = tmp_path / "ds"
    writer = DatasetWriter(out, manifest_for(campaign, CAMPAIGN.resolve(), rig))
    writer.write_skipped(build_plan(campaign, rig).skipped)
    writer.update_manifest(status="interrupted")
    writer.close()
    return out


def _rig_file(path: Path, rig: RigConfig, change) -> Path:
    data = rig.model_dump(mode="json")
    change(data)
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def _files(folder: Path) -> dict[str, bytes]:
    return {name: (folder / name).read_bytes() for name in ("dataset.json", "brdf.csv", "events.jsonl")}


@pytest.mark.parametrize("change, key", [
    (lambda d: d["devices"]["arm"].update(device_ids=[3, 4]), "key 'devices.arm.device_ids' is [3, 4], "
                                                              "the dataset's rig had [1, 2]"),
    (lambda d: d["devices"]["stage"].update(steps_per_degree=500.0), "key 'devices.stage.steps_per_degree'"),
    (lambda d: d["camera"].update(responsivity_e_per_cd_m2_s=1000.0), "key 'camera.responsivity_e_per_cd_m2_s'"),
    (lambda d: d["meter"].update(calibration_lx_per_a=2e9), "key 'meter.calibration_lx_per_a'"),
    (lambda d: d.update(attenuator=None) or d["devices"].update(attenuator=None), "key 'devices.attenuator"),
])
def test_a_new_rig_file_of_other_instruments_is_refused(tmp_path, capsys, change, key):
    """Before: `--rig` was ignored and the resume ran on the rig the dataset recorded."""
    recorded = simulated_rig()
    out = _unfinished(tmp_path, recorded)
    before = _files(out)
    new = _rig_file(tmp_path / "new.yaml", recorded, change)
    assert main(["run", "--resume", str(out), "--rig", str(new), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"rig: error: {new}: {key}") and "not the instruments" in err and "nothing was changed" in err
    assert _files(out) == before


def test_only_how_the_devices_are_reached_may_differ(tmp_path):
    recorded = RigConfig.model_validate(yaml.safe_load((ROOT / "campaigns" / "rigs" / "example-lab.yaml").read_text()))
    data = recorded.model_dump(mode="json")
    data["devices"]["meter"].update(address="/dev/ttyUSB7", timeout_s=5.0)
    data["devices"]["arm"]["address"] = "modbus-tcp://10.0.0.5:502"
    moved = RigConfig.model_validate(data)
    assert instrument_difference(recorded, moved) is None
    assert link_changes(recorded, moved) == {"devices.arm.address": ["modbus-tcp://192.168.10.21:502",
                                                                     "modbus-tcp://10.0.0.5:502"],
                                             "devices.meter.address": ["/dev/ttyUSB1", "/dev/ttyUSB7"],
                                             "devices.meter.timeout_s": [3.0, 5.0]}
    data["devices"]["camera"]["lens"] = "another-lens"          # a plug-in's option that is not an address
    assert "key 'devices.camera.options.lens' is 'another-lens'" in instrument_difference(
        recorded, RigConfig.model_validate(data))


def test_files_named_by_the_rig_file_are_compared_by_content(tmp_path):
    first, second = tmp_path / "a" / "cal.yaml", tmp_path / "b" / "cal.yaml"
    for path in (first, second):
        path.parent.mkdir()
        path.write_text("the same calibration\n")
    recorded = RigConfig.model_validate({"camera": {"calibration_file": str(first)}})
    copied = RigConfig.model_validate({"camera": {"calibration_file": str(second)}})
    assert instrument_difference(recorded, copied) is None
    second.write_text("another calibration\n")
    assert instrument_difference(recorded, copied) == (f"key 'camera.calibration_file': {second} is not the file "
                                                       f"the dataset's rig named ({first}), nor a copy of it")


@pytest.mark.parametrize("extra, what", [(["campaign.yaml"], "campaign file"), (["--out", "elsewhere"], "--out")])
def test_what_a_resume_cannot_use_is_refused_not_ignored(tmp_path, capsys, extra, what):
    out = _unfinished(tmp_path, simulated_rig())
    before = _files(out)
    args = ["run", extra[0], "--resume", str(out)] if extra[0].endswith(".yaml") else ["run", "--resume", str(out),
                                                                                      *extra]
    assert main(args) == 2
    assert f"give no {what} with it" in capsys.readouterr().err
    assert _files(out) == before


def test_a_resume_whose_rig_cannot_be_reached_counts_the_points_it_keeps(tmp_path):
    """Before: "0 completed points kept" for a resume that failed to connect, whatever the folder held."""
    from contextlib import contextmanager

    from rig.acquisition.execute import Prepared
    from rig.core.errors import DeviceError
    from rig.data.dataset_writer import DatasetWriter

    rig = simulated_rig()
    campaign = load_campaign(CAMPAIGN)
    out = _unfinished(tmp_path, rig)

    @contextmanager
    def unreachable():
        raise DeviceError("camera", "cannot connect: [Errno 111] Connection refused")
        yield

    done = [{"point_id": f"00-00{i}"} for i in range(3)]
    resumed = Prepared(campaign, CAMPAIGN, rig, build_plan(campaign, rig), out, writer=DatasetWriter.reopen(out),
                       done_rows=done)
    outcome = resumed.run(lambda c, r: unreachable())
    assert (outcome.status, outcome.measured, outcome.written) == ("failed", 3, True)
    assert events(out)[-1]["event"] == "failed" and manifest(out)["status"] == "failed"
