"""A full disk (issue 9, defect 6): refused before the run when the estimate does not fit, and a
clean failure during the run (one line naming the folder and the space needed, the rig made safe,
status `failed` when it can be written, the completed rows intact), then `--resume` completes.

ENOSPC is injected at the writer's one low-level write (`rig.data.append_log.write_all`) during an
in-process run on the simulated rig; a real small filesystem (tmpfs, needs root) is used where
mounting is permitted, and skipped with the reason otherwise.
"""

import csv
import errno
import json
import os
import shutil
import subprocess
import sys
from collections import namedtuple
from pathlib import Path

import numpy as np
import pytest

from repo_paths import ROOT
from rig.acquisition import diskspace
from rig.cli.main import main
from rig.config.campaign import load_campaign
from rig.config.rigfile import RigConfig
from rig.data import append_log
from rig.data import dataset_writer as ds_module
from rig.data.dataset_reader import load
from rig.data.dataset_writer import DatasetWriter, DiskFullError
from rig.data.images import write_luminance_exr
from rig.planning.plan import build_plan
from rig_process import pending_points, start_rig, wait_until

CAMPAIGN = ROOT / "tests" / "campaigns" / "e2e-reduced.yaml"
PAPER = ROOT / "campaigns" / "spieringhs2023-rm1.yaml"
Usage = namedtuple("Usage", "total used free")


def ids(folder: Path) -> list[str]:
    with open(folder / "brdf.csv", newline="") as fh:
        return [r["point_id"] for r in csv.DictReader(fh)]


def events(folder: Path) -> list[dict]:
    return [json.loads(line) for line in (folder / "events.jsonl").read_text().splitlines()]


def manifest(folder: Path) -> dict:
    return json.loads((folder / "dataset.json").read_text())


@pytest.fixture(scope="module")
def planned_ids():
    return sorted(p.point_id for p in build_plan(load_campaign(CAMPAIGN), RigConfig()).points)


class Fuse:
    """A disk that fills up: once brdf.csv holds `rows` rows, writes to the files named in `fail`
    raise ENOSPC (the file behind a descriptor is found through /proc/self/fd). Rows are written in
    batches (those an E⊥ reading brackets), so the file may hold a few more when it blows."""

    def __init__(self, rows: int, fail: tuple[str, ...]):
        self.rows, self.fail, self.written_rows, self.blown = rows, fail, -1, False   # -1: the header
        self._real = append_log.write_all

    def __call__(self, fd: int, data: bytes) -> None:
        name = Path(os.readlink(f"/proc/self/fd/{fd}")).name
        if name == "brdf.csv" and not self.blown:
            self.blown = self.written_rows >= self.rows
        if self.blown and name in self.fail:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self._real(fd, data)
        if name == "brdf.csv":
            self.written_rows += data.count(b"\n")


@pytest.mark.parametrize("fail, status", [
    (("brdf.csv",), "failed"),                                         # the log and manifest still fit
    (("brdf.csv", "events.jsonl", "dataset.json.tmp"), "running"),     # nothing fits: best-effort, no traceback
])
def test_enospc_mid_run_is_a_clean_failure_and_resume_completes(tmp_path, monkeypatch, capsys, planned_ids,
                                                                 fail, status):
    out = tmp_path / "ds"
    fuse = Fuse(rows=20, fail=fail)
    monkeypatch.setattr(append_log, "write_all", fuse)
    assert main(["run", str(CAMPAIGN), "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert "Traceback" not in "\n".join(err)
    line = err[-1]
    assert line.startswith("rig: campaign failed: ") and str(out) in line and "disk is full" in line
    assert "more needed to finish" in line and "free" in line
    assert manifest(out)["status"] == status
    if status == "failed":
        assert "DiskFullError" in manifest(out)["error"]
        last = events(out)[-1]
        assert last["event"] == "safe_state" and last["lamp_off"] and last["problems"] == []
    kept = ids(out)
    assert len(kept) == fuse.written_rows >= 20 and len(set(kept)) == len(kept)   # the completed rows, whole
    assert len(load(out)) == len(kept) and (out / "brdf.csv").read_bytes().endswith(b"\n")   # lines, once each
    assert not (out / ".reserve").exists()

    monkeypatch.setattr(append_log, "write_all", fuse._real)        # space freed
    assert main(["run", "--resume", str(out), "--quiet"]) == 0
    assert sorted(ids(out)) == planned_ids
    assert manifest(out)["status"] == "complete"


def test_first_enospc_raises_then_writes_are_best_effort(tmp_path, monkeypatch):
    writer = DatasetWriter(tmp_path / "ds", {"campaign": {"name": "x"}}, space_needed_bytes=10_000_000)
    assert (tmp_path / "ds" / ".reserve").stat().st_size == ds_module.RESERVE_BYTES

    def full(fd, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    monkeypatch.setattr(append_log, "write_all", full)
    with pytest.raises(DiskFullError, match=r"ds: the disk is full \(writing events.jsonl; .* free, about .* more"):
        writer.event("x")
    assert not (tmp_path / "ds" / ".reserve").exists()              # freed for the final records
    writer.event("y")                                               # best-effort from now on
    writer.update_manifest(status="failed")
    writer.append_row(dict.fromkeys(ds_module.BRDF_COLUMNS, 1.0))
    assert writer.unwritten_rows == 1 and writer.n_rows == 0
    writer.close()


def test_no_space_to_start_leaves_no_folder(tmp_path, monkeypatch):
    def full(fd, data):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    monkeypatch.setattr(append_log, "write_all", full)
    with pytest.raises(DiskFullError, match="nothing was written"):
        DatasetWriter(tmp_path / "a" / "ds", {"campaign": {"name": "x"}})
    assert not (tmp_path / "a").exists()


def test_run_is_refused_when_the_estimate_does_not_fit(tmp_path, monkeypatch, capsys):
    out = tmp_path / "new" / "ds"
    monkeypatch.setattr(diskspace.shutil, "disk_usage", lambda path: Usage(10**9, 10**9 - 300_000, 300_000))
    assert main(["run", str(PAPER), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and str(out) in err and "300.0 kB free" in err and "MB needed" in err
    assert not (tmp_path / "new").exists()


def test_the_estimate_covers_a_real_dataset_and_its_images(tmp_path):
    out = tmp_path / "ds"
    assert main(["run", str(CAMPAIGN), "--out", str(out), "--quiet"]) == 0
    plan = build_plan(load_campaign(CAMPAIGN), RigConfig())
    estimate = diskspace.estimate_dataset_bytes(len(plan.points), len(plan.skipped), RigConfig(), False)
    actual = ds_module.folder_size(out)
    assert actual < estimate < 4 * actual
    rig = RigConfig()
    frame = np.random.default_rng(1).normal(100.0, 3.0, (rig.camera.height_px, rig.camera.width_px))
    write_luminance_exr(tmp_path / "f.exr", frame, {"point_id": "00-001"})
    size = (tmp_path / "f.exr").stat().st_size                          # uncompressed: the bound is tight
    assert diskspace.image_bytes(rig) - diskspace.EXR_HEADER_BYTES < size <= diskspace.image_bytes(rig)
    with_images = diskspace.estimate_dataset_bytes(len(plan.points), len(plan.skipped), rig, True)
    assert with_images - estimate == len(plan.points) * diskspace.image_bytes(rig)


# -- a real small filesystem -----------------------------------------------------------------

@pytest.fixture
def small_disk(tmp_path):
    """A tmpfs of a given size mounted in tmp_path (root only); unmounted afterwards."""
    mounts = []

    def mount(size: str) -> Path:
        where = tmp_path / f"disk{len(mounts)}"
        where.mkdir()
        proc = subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(where)],
                              capture_output=True, text=True)
        if proc.returncode != 0:
            pytest.skip(f"cannot mount a tmpfs here (needs root / CAP_SYS_ADMIN): {proc.stderr.strip()}")
        mounts.append(where)
        return where
    yield mount
    for where in mounts:
        subprocess.run(["umount", "-l", str(where)], capture_output=True)


def test_paper_campaign_on_a_300_kb_filesystem_is_refused_before_anything_is_written(small_disk, capsys):
    disk = small_disk("300k")
    assert main(["run", str(PAPER), "--out", str(disk / "rm1"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rig: error: ") and err.count("\n") == 1
    assert str(disk / "rm1") in err and "MB needed" in err and "kB free" in err
    assert list(disk.iterdir()) == []


def test_a_filesystem_filling_up_mid_run_fails_cleanly_and_the_moved_folder_resumes(small_disk, tmp_path,
                                                                                    planned_ids):
    disk = small_disk("600k")
    out = disk / "ds"
    proc = start_rig("run", str(CAMPAIGN), "--out", str(out), "--quiet")
    wait_until(lambda: pending_points(out) >= 10, proc, "10 points")
    fd = os.open(disk / "filler", os.O_WRONLY | os.O_CREAT)   # somebody else fills the disk
    try:
        while True:
            os.write(fd, bytes(4096))
    except OSError as exc:
        assert exc.errno == errno.ENOSPC
    finally:
        os.close(fd)
    assert proc.wait(timeout=60) == 1
    err = proc.stderr.read()
    assert "Traceback" not in err and "disk is full" in err and str(out) in err
    assert manifest(out)["status"] == "failed"            # the reserve made room for the manifest
    assert events(out)[-1]["event"] == "safe_state" and events(out)[-1]["lamp_off"]
    before = ids(out)
    assert 0 < len(before) < len(planned_ids) and len(set(before)) == len(before)

    moved = tmp_path / "moved"
    shutil.copytree(out, moved)                           # carried to a disk with room
    resumed = subprocess.run([sys.executable, "-m", "rig.cli.main", "run", "--resume", str(moved), "--quiet"],
                             capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert resumed.returncode == 0, resumed.stderr
    assert sorted(ids(moved)) == planned_ids and ids(moved)[:len(before)] == before
    assert manifest(moved)["status"] == "complete"


def test_an_image_that_does_not_fit_is_a_disk_full_error(tmp_path, monkeypatch):
    writer = DatasetWriter(tmp_path / "ds", {"campaign": {"name": "x"}})

    def half_written(path, pixels, metadata):
        Path(path).write_bytes(b"half")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
    monkeypatch.setattr(ds_module, "write_luminance_exr", half_written)
    with pytest.raises(DiskFullError, match="writing images/00-001.exr"):
        writer.write_image("00-001", np.zeros((4, 4)), {})
    assert not (tmp_path / "ds" / "images" / "00-001.exr").exists()     # no half image left
    writer.close()
