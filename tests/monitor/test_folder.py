"""rig.monitor.folder on hand-written dataset folders (docs/dataset.md) that grow line by line as `rig run`
writes them: its counts, phase, ETA and incremental changes, a torn last line, and how runs end.

The manifests carry campaigns/quick.yaml on the built-in simulated rig, whose plan has 62 points to
measure and 19 skipped (`rig plan campaigns/quick.yaml`).
"""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from repo_paths import CAMPAIGNS
from rig.config.campaign import load_campaign
from rig.config.rigfile import simulated_rig
from rig.data.dataset_format import BRDF_COLUMNS, FORMAT, csv_line
from rig.monitor.folder import FolderFollower
from rig.monitor.records import point_record, summarize_event

TO_MEASURE = 62
#: Wall seconds per rig second of the hand-written runs (a paced simulated rig).
WALL_PER_RIG = 0.1
START = datetime(2026, 1, 1, tzinfo=UTC)


def utc(rig_s: float) -> str:
    return (START + timedelta(seconds=rig_s * WALL_PER_RIG)).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def manifest(**changes) -> dict:
    return {"format": FORMAT, "format_version": "1.1", "created_utc": utc(0), "status": "running",
            "campaign": {"name": "quick", "content": load_campaign(CAMPAIGNS / "quick.yaml").model_dump(mode="json")},
            "sample": {"id": "RM1-sim"}, "rig": {"name": "simulated", "simulated": True,
                                                 "config": simulated_rig().model_dump(mode="json")},
            "software": {"name": "rig", "version": "0"}, "counts": {}, **changes}


def row(point_id: str, rig_s: float, theta_o: float = 30.0, phi_o: float = 180.0, flags: str = "") -> dict:
    """A brdf.csv row at θi = 30°, φi = 0° (the numbers are plausible, not simulated)."""
    values: dict[str, object] = {c: 0.001 for c in BRDF_COLUMNS}
    values.update(point_id=point_id, series=1, theta_i_deg=30.0, phi_i_deg=0.0, theta_o_deg=theta_o, phi_o_deg=phi_o,
                  brdf_per_sr=0.2, u_brdf_per_sr=0.002, exposures_s="0.01", flags=flags, time_utc=utc(rig_s),
                  rig_time_s=rig_s, filter_position=0, illuminance_interpolated=1)
    return values


class Folder:
    """A dataset folder written the way rig.data.dataset_writer writes one."""

    def __init__(self, path: Path, **manifest_changes):
        self.path = path
        path.mkdir()
        self.set_manifest(**manifest_changes)
        (path / "skipped.csv").write_text("point_id,theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,reason\n"
                                          "00-001,0,0,89,0,below_horizon\n00-002,0,0,88,0,beyond_max_view_theta\n"
                                          "00-003,0,0,87,0,below_horizon\n")
        self.append("brdf.csv", csv_line(BRDF_COLUMNS))
        (path / ".lock").write_text(f"pid {os.getpid()} host {socket.gethostname()}\n")   # the writer: alive
        self.follower = FolderFollower(path)

    def set_manifest(self, **changes) -> None:
        tmp = self.path / "dataset.json.tmp"
        tmp.write_text(json.dumps(manifest(**changes)))
        tmp.replace(self.path / "dataset.json")

    def append(self, name: str, text: str) -> None:
        with (self.path / name).open("a") as fh:
            fh.write(text)

    def event(self, kind: str, rig_s: float | None = None, **fields) -> None:
        record = {"time_utc": utc(rig_s or 0.0), "event": kind, **fields}
        if rig_s is not None:
            record["rig_time_s"] = rig_s
        self.append("events.jsonl", json.dumps(record) + "\n")

    def pending(self, point_id: str, rig_s: float) -> None:
        self.event("point_pending", row=row(point_id, rig_s))

    def row(self, point_id: str, rig_s: float, **kw) -> None:
        r = row(point_id, rig_s, **kw)
        self.append("brdf.csv", csv_line(r[c] for c in BRDF_COLUMNS))

    def look(self, since: int = 0) -> dict:
        self.follower.update()
        return self.follower.snapshot(since)


def warm(f: Folder) -> None:
    """Connected, lamp on at rig time 5 s, warm at 100 s, E⊥ read."""
    f.event("devices", identities={"lamp": "SM15K"}, simulated=True)
    f.event("lamp_on", 5.0, current_a=4.17, voltage_v=11.6)
    f.event("warmup_stable", 100.0, illuminance_lx=5000.0, change_rel=0.001, warmup_s=95.0, lamp_voltage_v=12.0)
    f.event("illuminance", 101.0, illuminance_normal_lx=4990.0, u_lx=4.0, readings=5)


def test_a_run_is_followed_line_by_line(tmp_path):
    f = Folder(tmp_path / "run")
    s = f.look()
    assert (s["phase"], s["progress"]["done"], s["progress"]["to_measure"]) == ("starting", 0, TO_MEASURE)
    assert s["progress"]["skipped"] == 3
    assert [(k["reason"], k["count"]) for k in s["skipped"]] == [("below_horizon", 2), ("beyond_max_view_theta", 1)]
    f.event("devices", identities={"lamp": "SM15K"}, simulated=True)
    f.event("lamp_on", 5.0, current_a=4.17, voltage_v=11.6)
    s = f.look(s["next"])
    assert s["phase"] == "warm-up"
    assert [c["k"] for c in s["changes"]] == ["ev", "l", "ev"]         # only what is new since the last look
    assert s["changes"][1] == {"k": "l", "t": 5.0, "i": 4.17, "v": 11.6, "r": 0}
    f.event("warmup_stable", 100.0, illuminance_lx=5000.0, change_rel=0.001, warmup_s=95.0, lamp_voltage_v=12.0)
    f.event("illuminance", 101.0, illuminance_normal_lx=4990.0, u_lx=4.0, readings=5)
    s = f.look(s["next"])
    assert s["phase"] == "measuring"
    assert {"k": "e", "t": 101.0, "lx": 4990.0, "u": 4.0, "r": 0} in s["changes"]
    f.pending("01-000", 110.0)
    s = f.look(s["next"])
    assert s["progress"]["done"] == 1 and s["progress"]["pending"] == 1 and s["progress"]["in_csv"] == 0
    assert [c["id"] for c in s["changes"] if c["k"] == "p"] == ["01-000"]
    f.pending("01-001", 120.0)
    f.event("illuminance", 125.0, illuminance_normal_lx=4991.0, u_lx=4.0, readings=5)
    f.row("01-000", 110.0)
    f.row("01-001", 120.0, flags="retried")
    s = f.look(s["next"])
    assert s["progress"] == {"done": 2, "to_measure": TO_MEASURE, "in_csv": 2, "pending": 0, "skipped": 3}
    assert s["flags"] == {"retried": 1}
    assert {b["component"] for b in s["budget"]} >= {"u_rel_noise", "u_rel_drift"}
    assert s["budget"][0]["median_u_rel"] == pytest.approx(0.001)
    assert s["rig_time_s"] == pytest.approx(125.0)


def test_a_torn_last_line_waits_for_its_end(tmp_path):
    f = Folder(tmp_path / "run")
    warm(f)
    line = csv_line(row("01-000", 110.0)[c] for c in BRDF_COLUMNS)
    f.append("brdf.csv", line[:40])
    event = json.dumps({"time_utc": utc(111.0), "event": "suspended", "device": "lamp", "reason": "x"}) + "\n"
    f.append("events.jsonl", event[:25])
    s = f.look()
    assert s["progress"]["done"] == 0 and s["phase"] == "measuring" and s["bad_lines"] == 0
    f.append("brdf.csv", line[40:])
    f.append("events.jsonl", event[25:])
    s = f.look()
    assert s["progress"]["done"] == 1 and s["phase"] == "paused" and s["bad_lines"] == 0


def test_a_pause_shows_its_reason_discards_and_keeps_the_eta(tmp_path):
    f = Folder(tmp_path / "run")
    warm(f)
    f.pending("01-000", 110.0)
    f.pending("01-001", 120.0)
    f.pending("01-002", 130.0)
    s = f.look()
    # Measuring from rig time 100 s to 130 s for 3 points: 10 s each, 59 left.
    assert s["eta"]["rig_s"] == pytest.approx(59 * 10.0)
    assert s["eta"]["wall_per_rig"] == pytest.approx(WALL_PER_RIG, rel=1e-3)
    assert s["eta"]["wall_s"] == pytest.approx(59 * 10.0 * WALL_PER_RIG, rel=1e-3)
    reason = "lamp current 0.000 A at 0.00 V with 4.170 A set: lamp burnt out or circuit open"
    f.event("points_discarded", 131.0, point_ids=["01-002"], reason="lamp")
    f.event("suspended", 131.0, device="lamp", reason=reason)
    f.event("lamp_on", 400.0, current_a=4.17, voltage_v=11.6)        # a pause's end re-warms: not measuring
    s2 = f.look(s["next"])
    assert s2["phase"] == "warm-up" and s2["progress"]["done"] == 2
    assert {"k": "d", "id": "01-002"} in s2["changes"]
    f2 = Folder(tmp_path / "paused")
    warm(f2)
    f2.pending("01-000", 110.0)
    f2.event("suspended", 131.0, device="lamp", reason=reason)
    s3 = f2.look()
    assert s3["phase"] == "paused" and s3["detail"] == f"lamp: {reason}"
    assert s3["eta"]["rig_s"] == pytest.approx((TO_MEASURE - 1) * 31.0)       # measuring 100 → 131 s for 1 point
    f2.event("resumed", 300.0, device="lamp", waited_s=169.0)
    assert f2.look()["phase"] == "measuring"


def test_a_finished_run_reads_the_same_and_has_no_eta(tmp_path):
    f = Folder(tmp_path / "run")
    warm(f)
    f.row("01-000", 110.0)
    f.event("parked", 120.0, position_deg=[0, 0, 0, 0])
    f.event("safe_state", 121.0, lamp_off=True, problems=[])
    f.set_manifest(status="complete", counts={"planned": 2, "measured": 1, "skipped": 1, "not_measured": 0})
    s = f.look()
    assert (s["phase"], s["status"]) == ("finished", "complete")
    assert s["progress"]["to_measure"] == 1 and s["progress"]["done"] == 1
    assert s["eta"] == {"rig_s": None, "wall_s": None, "wall_per_rig": None}


def test_an_interrupted_run_says_why(tmp_path):
    f = Folder(tmp_path / "run")
    warm(f)
    f.event("stop_requested", 111.0, reason="Ctrl+C")
    assert f.look()["phase"] == "stopping"
    f.event("interrupted", 112.0, graceful=True, reason="Ctrl+C", measured=0)
    f.event("safe_state", 113.0, lamp_off=True, problems=[])
    f.set_manifest(status="interrupted")
    s = f.look()
    assert (s["phase"], s["detail"]) == ("interrupted", "Ctrl+C")


def test_a_failed_run_shows_the_manifest_error(tmp_path):
    f = Folder(tmp_path / "run")
    warm(f)
    f.set_manifest(status="failed", error="arm: alarm 0x30")
    assert (f.look()["phase"], f.look()["detail"]) == ("failed", "arm: alarm 0x30")


def test_a_running_manifest_whose_writer_died_is_abandoned(tmp_path):
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, text=True)
    f = Folder(tmp_path / "run")
    warm(f)
    (f.path / ".lock").write_text(f"pid {dead.stdout.strip()} host {socket.gethostname()}\n")
    assert f.look()["phase"] == "abandoned"
    (f.path / ".lock").write_text(f"pid {os.getpid()} host {socket.gethostname()}\n")
    assert f.look()["phase"] == "measuring"


def test_a_missing_folder_is_waited_for_and_a_remade_one_starts_over(tmp_path):
    follower = FolderFollower(tmp_path / "later")
    follower.update()
    assert follower.snapshot()["phase"] == "waiting"
    f = Folder(tmp_path / "later")
    warm(f)
    f.pending("01-000", 110.0)
    follower.update()
    first = follower.snapshot()
    assert first["progress"]["done"] == 1
    (f.path / "events.jsonl").write_text("")                       # the folder made again by another run
    follower.update()
    again = follower.snapshot(first["next"])
    assert again["generation"] != first["generation"] and again["progress"]["done"] == 0


def test_a_view_is_placed_in_the_plane_of_incidence_as_rig_plot_does():
    specular = point_record(row("01-000", 1.0, theta_o=30.0, phi_o=180.0))
    retro = point_record(row("01-001", 1.0, theta_o=20.0, phi_o=0.0))
    aside = point_record(row("01-002", 1.0, theta_o=30.0, phi_o=90.0))
    assert specular["x"] == pytest.approx(-30.0) and retro["x"] == pytest.approx(20.0)
    assert aside["x"] is None and aside["to"] == pytest.approx(30.0)


def test_an_event_summary_is_one_bounded_line():
    text = summarize_event({"event": "retry", "time_utc": "x", "rig_time_s": 1.0, "device": "arm",
                            "error": "no reply " * 100, "rate": 1.23456789})
    assert text.startswith("device=arm error=no reply") and len(text) <= 240 and "\n" not in text
    assert "rate=1.235" in summarize_event({"rate": 1.23456789})
