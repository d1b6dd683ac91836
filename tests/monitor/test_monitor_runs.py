"""The monitor across resumes and during the warm-up (issue 35): E⊥ and lamp readings on the campaign's rig-time
axis with the run that took them, an old dataset's restarted rig time placed after the previous run, and the
warm-up's readings, expected rest and an ETA that includes it."""

from __future__ import annotations

import pytest
from shared import Folder

EXPECTED = {"seconds": 400.0, "source": "a test's"}


def run_entry(offset: float) -> dict:
    return {"run": 0, "rig_time_offset_s": offset, "rig_time_s": 0.0, "status": "running", "warmups": [],
            "expected_warmup": EXPECTED}


def readings(s: dict) -> list[tuple[float, int]]:
    return [(c["t"], c["r"]) for c in s["changes"] if c["k"] in ("e", "l")]


def test_readings_carry_their_run_on_the_campaign_axis(tmp_path):
    f = Folder(tmp_path / "ds", runs=[run_entry(0.0), run_entry(500.0)])
    f.event("lamp_on", 5.0, current_a=4.17, voltage_v=11.6)
    f.event("illuminance", 400.0, illuminance_normal_lx=5000.0, u_lx=4.0)
    f.event("safe_state", 500.0)
    f.event("resume", previous_status="interrupted")
    f.event("lamp_on", 505.0, current_a=4.17, voltage_v=11.6)
    f.event("illuminance", 900.0, illuminance_normal_lx=4990.0, u_lx=4.0)
    assert readings(f.look()) == [(5.0, 0), (400.0, 0), (505.0, 1), (900.0, 1)]


def test_an_old_datasets_second_run_is_placed_after_the_first(tmp_path):
    f = Folder(tmp_path / "ds")                                   # no `runs`: rig time restarted at the resume
    f.event("illuminance", 400.0, illuminance_normal_lx=5000.0, u_lx=4.0)
    f.event("safe_state", 500.0)
    f.event("resume", previous_status="interrupted")
    f.event("devices")
    f.event("lamp_on", 5.0, current_a=4.17, voltage_v=11.6)
    s = f.look()
    assert readings(s) == [(400.0, 0), (505.0, 1)] and s["rig_time_s"] == 505.0


def test_the_warm_up_shows_its_readings_the_rest_and_an_eta_that_includes_it(tmp_path):
    """Issue 35: during the warm-up the monitor showed ETA "–" and looked hung."""
    f = Folder(tmp_path / "ds", runs=[run_entry(0.0)])
    f.event("devices", identities={})
    f.event("lamp_on", 5.0, current_a=4.17, voltage_v=11.6)
    s = f.look()
    assert s["phase"] == "warm-up" and s["warmup"]["expected_s"] == 400.0 and s["warmup"]["source"] == "a test's"
    plan_s = s["eta"]["rig_s"] - 400.0
    assert plan_s > 60                                            # the quick campaign's moves, after the warm-up
    f.event("warmup_wait", 65.0, warmup_s=60.0, expected_left_s=340.0)     # no reading in the minimum wait
    s = f.look()
    assert s["warmup"]["elapsed_s"] == 60.0 and s["warmup"]["left_s"] == 340.0 and s["warmup"]["last"] is None
    f.event("warmup_check", 365.0, illuminance_lx=4987.0, change_rel=0.004, stable_rel=0.002, warmup_s=360.0,
            expected_left_s=60.0)
    s = f.look()
    assert s["warmup"]["last"]["change"] == 0.004 and s["warmup"]["left_s"] == 60.0
    assert s["eta"]["rig_s"] == pytest.approx(60.0 + plan_s)
    assert any(c["k"] == "w" and c["lx"] == 4987.0 for c in s["changes"])
    f.event("warmup_stable", 425.0, illuminance_lx=4990.0, change_rel=0.001, warmup_s=420.0, lamp_voltage_v=12.0)
    assert f.look()["warmup"] is None
