"""Dataset folder: contract columns, append-and-fsync rows, atomic manifest, refusals."""

import csv
import errno
import json
import os
import threading

import pytest

from rig.data.dataset_format import BRDF_COLUMNS, SKIPPED_COLUMNS, DatasetError
from rig.data.dataset_writer import DatasetWriter, DiskFullError
from rig.planning.points import SkippedPoint

CONTRACT_COLUMNS = [
    "point_id", "series", "theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg",
    "brdf_per_sr", "u_brdf_per_sr", "luminance_cd_m2", "u_luminance_cd_m2",
    "illuminance_lx", "illuminance_normal_lx",
    "stage_vertical_deg", "stage_normal_deg", "arm_azimuth_deg", "arm_polar_deg",
    "exposures_s", "saturated_fraction", "flags", "time_utc", "rig_time_s"]


def row(pid="00-000", **over):
    r = {c: 1.5 for c in BRDF_COLUMNS}
    r.update(point_id=pid, series=0, exposures_s=[0.01, 0.0025], flags="", time_utc="2026-01-01T00:00:00Z",
             n_frames=2)
    r.update(over)
    return r


def test_columns_follow_contract():
    assert list(BRDF_COLUMNS[:len(CONTRACT_COLUMNS)]) == CONTRACT_COLUMNS
    assert SKIPPED_COLUMNS == ("point_id", "theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg", "reason")


def test_rows_are_on_disk_before_close(tmp_path):
    w = DatasetWriter(tmp_path / "ds", {"campaign": {"name": "t"}})
    w.append_row(row("00-000", brdf_per_sr=0.123456789012345))
    w.append_row(row("00-001", flags="retried;low_signal"))
    w.event("retry", point_id="00-001")
    # read while the writer is still open: a crash now must lose nothing
    with open(tmp_path / "ds" / "brdf.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["point_id"] for r in rows] == ["00-000", "00-001"]
    assert float(rows[0]["brdf_per_sr"]) == 0.123456789012345      # full precision
    assert rows[0]["exposures_s"] == "0.01;0.0025"
    assert rows[1]["flags"] == "retried;low_signal"
    events = [json.loads(line) for line in (tmp_path / "ds" / "events.jsonl").read_text().splitlines()]
    assert events[0]["event"] == "retry" and events[0]["point_id"] == "00-001"
    w.close()


def test_a_batch_of_rows_is_one_write_and_one_fsync_all_or_nothing(tmp_path, monkeypatch):
    w = DatasetWriter(tmp_path / "ds", {})
    syncs = []
    monkeypatch.setattr(os, "fsync", lambda fd: syncs.append(fd))
    w.append_rows([row("00-000"), row("00-001"), row("00-002")])
    assert len(syncs) == 1 and w.n_rows == 3
    with pytest.raises(ValueError, match="non-finite"):
        w.append_rows([row("00-003"), row("00-004", brdf_per_sr=float("inf"))])
    w.append_rows([])
    assert len(syncs) == 1 and w.n_rows == 3
    with open(tmp_path / "ds" / "brdf.csv", newline="") as fh:
        assert [r["point_id"] for r in csv.DictReader(fh)] == ["00-000", "00-001", "00-002"]
    w.close()


def test_manifest_atomic_and_complete(tmp_path):
    w = DatasetWriter(tmp_path / "ds", {"campaign": {"name": "t"}})
    m = json.loads((tmp_path / "ds" / "dataset.json").read_text())
    assert m["format"] == "rig-brdf-dataset" and m["status"] == "running" and "conventions" in m
    w.update_manifest(status="complete", counts={"measured": 2})
    m = json.loads((tmp_path / "ds" / "dataset.json").read_text())
    assert m["status"] == "complete" and m["counts"]["measured"] == 2 and m["campaign"]["name"] == "t"
    assert not list((tmp_path / "ds").glob("*.tmp"))
    assert not (tmp_path / "ds" / "images").exists()     # only what the campaign asks for
    w.close()


def test_skipped_csv(tmp_path):
    w = DatasetWriter(tmp_path / "ds", {})
    w.write_skipped([SkippedPoint("01-004", 1, 85.0, 0.0, 89.5, 180.0, "below_horizon")])
    with open(tmp_path / "ds" / "skipped.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert rows == [{"point_id": "01-004", "theta_i_deg": "85.0", "phi_i_deg": "0.0",
                     "theta_o_deg": "89.5", "phi_o_deg": "180.0", "reason": "below_horizon"}]
    w.close()


def test_refuses_existing_dataset(tmp_path):
    (tmp_path / "ds").mkdir()
    (tmp_path / "ds" / "brdf.csv").write_text("precious\n")
    with pytest.raises(DatasetError, match="already exists and is not empty"):
        DatasetWriter(tmp_path / "ds", {})
    assert (tmp_path / "ds" / "brdf.csv").read_text() == "precious\n"


@pytest.mark.skipif(os.geteuid() == 0, reason="root can write anywhere")
def test_refuses_unwritable_folder(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    with pytest.raises(DatasetError, match="not writable"):
        DatasetWriter(ro / "ds", {})


def test_refuses_output_path_that_is_a_file(tmp_path):
    (tmp_path / "file").write_text("")
    with pytest.raises(DatasetError, match="not writable"):
        DatasetWriter(tmp_path / "file" / "ds", {})


def test_refuses_non_finite_and_incomplete_rows(tmp_path):
    w = DatasetWriter(tmp_path / "ds", {})
    with pytest.raises(ValueError, match="non-finite"):
        w.append_row(row(brdf_per_sr=float("nan")))
    bad = row()
    del bad["flags"]
    with pytest.raises(ValueError, match="lacks flags"):
        w.append_row(bad)
    w.close()


def test_an_event_synced_behind_is_written_at_once_and_on_disk_before_the_next_write(tmp_path, monkeypatch):
    """`point_pending` records: written before the call returns (a killed process loses nothing), fsync'ed on
    another thread, and every later write waits for that fsync, so what is on disk is a prefix of what was
    written."""
    w = DatasetWriter(tmp_path / "ds", {})
    log = tmp_path / "ds" / "events.jsonl"
    release, syncs = threading.Event(), []

    def slow_fsync(fd):
        release.wait(5.0)
        syncs.append((fd, threading.current_thread() is threading.main_thread(), log.read_text().count("\n")))
    monkeypatch.setattr(os, "fsync", slow_fsync)
    w.event_synced_behind("point_pending", row={"point_id": "00-000"})
    assert json.loads(log.read_text())["row"] == {"point_id": "00-000"} and syncs == []    # written, not yet synced
    threading.Timer(0.05, release.set).start()
    w.event("illuminance", value_lx=100.0)          # waits for the fsync in flight, then writes and syncs
    assert [(main, lines) for _, main, lines in syncs] == [(False, 1), (True, 2)]
    w.close()


def test_a_failed_fsync_behind_cuts_its_line_and_fails_the_next_write(tmp_path, monkeypatch):
    w = DatasetWriter(tmp_path / "ds", {})
    w.event("devices")

    def full(fd):
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    monkeypatch.setattr(os, "fsync", full)
    w.event_synced_behind("point_pending", row={"point_id": "00-000"})
    monkeypatch.undo()
    with pytest.raises(DiskFullError, match="writing events.jsonl"):
        w.event("illuminance")
    kinds = [json.loads(line)["event"] for line in (tmp_path / "ds" / "events.jsonl").read_text().splitlines()]
    assert kinds == ["devices"]
    w.close()
