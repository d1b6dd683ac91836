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

import pytest
from shared import WALL_PER_RIG, Folder, row, utc, warm

from rig.data.dataset_format import BRDF_COLUMNS, csv_line
from rig.monitor.folder import FolderFollower
from rig.monitor.records import point_record, summarize_event

TO_MEASURE = 62


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
