"""Run engine over the protocol rig: completed points kept, lamp off and axes stopped on every path.

Faults are injected into the simulators' protocol peers (Modbus, SCPI, serial) while the
campaign runs, from the progress callback; the camera, an in-process device, is wrapped.
"""

import json
import math

import numpy as np
import pytest
import yaml
from shared import at_point, events, rows, run, small_campaign, suspenders_run

from repo_paths import ROOT
from rig.acquisition.engine import Runner
from rig.acquisition.execute import manifest_for
from rig.cli.main import main
from rig.config.rigfile import RigConfig
from rig.core.errors import DeviceError
from rig.data.dataset_writer import DatasetWriter
from rig.data.images import read_luminance_exr
from rig.planning.plan import build_plan
from rig.simulators.rig import SimulatedRig


class FailingCapture:
    """Wraps the simulated camera: the n-th capture raises the given error (once, or for ever)."""

    def __init__(self, camera, at: int, error: DeviceError, persistent: bool):
        self._camera, self._at, self._error, self._persistent = camera, at, error, persistent
        self.calls = 0

    def __getattr__(self, name):
        return getattr(self._camera, name)

    def capture(self, exposure_s, window=None):
        self.calls += 1
        if self.calls == self._at or (self._persistent and self.calls > self._at):
            raise self._error
        return self._camera.capture(exposure_s, window)


def assert_failed_cleanly(tmp_path, runner, plan, lamp_on, moving, message):
    kept = rows(tmp_path / "ds")
    assert 0 < len(kept) < len(plan.points) and len(kept) == runner.measured
    manifest = json.loads((tmp_path / "ds" / "dataset.json").read_text())
    assert manifest["status"] == "failed" and message in manifest["error"]
    assert manifest["counts"]["measured"] == len(kept)
    assert not lamp_on and not moving
    ev = events(tmp_path / "ds")
    kinds = [e["event"] for e in ev]
    assert kinds[-1] == "safe_state" and ev[-1]["lamp_off"] and "failed" in kinds[-3:]
    # every point written ahead is in brdf.csv unless it was discarded for a re-take
    pending = {e["row"]["point_id"] for e in ev if e["event"] == "point_pending"}
    discarded = {pid for e in ev if e["event"] == "points_discarded" for pid in e["point_ids"]}
    assert pending - discarded == {r["point_id"] for r in kept}


def test_complete_run_switches_lamp_off(tmp_path):
    status, _, runner, plan, lamp_on, moving = run(tmp_path, small_campaign())
    assert status == "complete"
    assert not lamp_on and not moving
    assert len(rows(tmp_path / "ds")) == len(plan.points) == 16
    identities = events(tmp_path / "ds")[0]["identities"]
    assert identities["lamp"].startswith("DELTA ELEKTRONIKA") and "P9710" in identities["meter"]


def test_persistent_camera_failure_keeps_points_and_makes_safe(tmp_path):
    err = DeviceError("camera", "no answer after 3 s", transient=False)
    status, error, runner, plan, lamp_on, moving = run(
        tmp_path, small_campaign(), camera_fault=lambda cam: FailingCapture(cam, at=20, error=err, persistent=True))
    assert status == "raised" and error is err
    assert_failed_cleanly(tmp_path, runner, plan, lamp_on, moving, "camera: no answer")


def test_modbus_exception_stops_cleanly_naming_the_axis(tmp_path):
    status, error, runner, plan, lamp_on, moving = run(
        tmp_path, small_campaign(), inject=at_point(5, lambda peers: peers["arm"].inject("exception")))
    assert status == "raised" and "Modbus exception" in str(error)
    assert_failed_cleanly(tmp_path, runner, plan, lamp_on, moving, "Modbus exception")


def test_axis_alarm_stops_cleanly(tmp_path):
    status, error, runner, plan, lamp_on, moving = run(
        tmp_path, small_campaign(), inject=at_point(3, lambda peers: peers["arm"].inject("alarm", axis=1)))
    assert status == "raised" and "alarm 0x10" in str(error)
    assert_failed_cleanly(tmp_path, runner, plan, lamp_on, moving, "alarm 0x10")


@pytest.mark.parametrize("peer, fault", [("arm", "no_reply"), ("stage", "disconnect"), ("arm", "garbled"),
                                         ("lamp", "garbled"), ("lamp", "disconnect"), ("meter", "short"),
                                         ("meter", "garbled")])
def test_transient_protocol_faults_cost_a_retry_event(tmp_path, peer, fault):
    """The meter's next exchange is the next series' E⊥; the lamp's a check or a watchdog feed (which reports a
    failed feed instead of retrying: the watchdog is fed again a feed period later)."""
    campaign = small_campaign(incidence=[{"phi": 0, "theta": [0, 30, 60]}])
    status, _, runner, plan, lamp_on, moving = run(
        tmp_path, campaign, inject=at_point(4, lambda peers: peers[peer].inject(fault)))
    assert status == "complete"
    assert len(rows(tmp_path / "ds")) == len(plan.points)
    assert not lamp_on and not moving
    retries = [e for e in events(tmp_path / "ds") if e["event"] in ("retry", "watchdog_feed_failed")]
    assert len(retries) == 1
    assert retries[0]["device"] in (peer, "arm_azimuth", "arm_polar", "stage_vertical", "stage_normal")


def lit_rows_only(folder, runner, burnt_s, replaced_s=math.inf):
    """No row of brdf.csv was measured between a burn-out and the new lamp (times on the rig clock)."""
    dark = [r["point_id"] for r in rows(folder) if burnt_s <= float(r["rig_time_s"]) + runner.t0 < replaced_s]
    assert dark == []


def test_lamp_burnout_pauses_then_stops_cleanly_naming_the_lamp(tmp_path):
    campaign = small_campaign(suspenders={"max_wait_s": 600})
    burnt = []

    def burn_out(peers):
        burnt.append(peers["lamp"].world.clock.now())
        peers["lamp"].inject("burnout")
    status, error, runner, plan, lamp_on, moving = run(tmp_path, campaign, inject=at_point(10, burn_out))
    assert status == "raised" and str(error).startswith("lamp: paused 600 s and still: lamp current 0.000 A")
    assert "burnt out" in str(error)
    # the points since the last passing lamp check may have been dark: discarded, the first series' rows kept
    assert 8 <= runner.measured < 10
    lit_rows_only(tmp_path / "ds", runner, burnt[0])
    assert_failed_cleanly(tmp_path, runner, plan, lamp_on, moving, "burnt out")
    kinds = [e["event"] for e in events(tmp_path / "ds")]
    assert kinds.index("suspended") < kinds.index("suspend_timeout") < kinds.index("failed")


@pytest.mark.parametrize("burnt_after", [6, 7])
def test_lamp_burnout_then_replacement_resumes_and_retakes(tmp_path, burnt_after):
    """The lamp is checked every few seconds of rig time, not before every point: a burn-out mid-series still
    pauses the run, and every point measured since the last passing check is discarded and measured again."""
    state = {}

    def inject(peers, done):
        if done == burnt_after and "burnt" not in state:
            state["burnt"] = peers["lamp"].world.clock.now()
            peers["lamp"].inject("burnout")
        elif "burnt" in state and "new" not in state and peers["lamp"].world.clock.now() > state["burnt"] + 200:
            state["new"] = peers["lamp"].world.clock.now()
            peers["lamp"].world.lamp.replace()          # the operator fits a new lamp
    ev, runner = suspenders_run(tmp_path, inject)          # complete, each point once
    kinds = [e["event"] for e in ev]
    assert "suspended" in kinds and "resumed" in kinds and kinds.count("warmup_stable") == 2
    discarded = next(e for e in ev if e["event"] == "points_discarded")
    pending_before = [e["row"]["point_id"] for e in ev[:ev.index(discarded)] if e["event"] == "point_pending"]
    assert discarded["reason"] == "lamp" and 1 <= len(discarded["point_ids"]) <= 5
    assert discarded["point_ids"] == pending_before[-len(discarded["point_ids"]):]    # the last ones measured
    assert next(e for e in ev if e["event"] == "resumed")["waited_s"] >= 200
    lit_rows_only(tmp_path / "ds", runner, state["burnt"], state["new"])


def test_a_lamp_out_just_before_an_illuminance_reading_pauses_instead_of_failing(tmp_path):
    """The lamp goes out after a series' last point, so the next thing to see it is the meter (no light, a
    persistent error) at the next series, before any point's suspender check: the run pauses for the lamp."""
    state = {}
    campaign = small_campaign(incidence=[{"phi": 0, "theta": [0, 30, 60]}], ordering="table")

    def inject(peers, done):
        if done == 8 and "burnt" not in state:                 # the first series (8 views) is done
            state["burnt"] = peers["lamp"].world.clock.now()
            peers["lamp"].inject("burnout")
        elif "burnt" in state and "new" not in state and peers["lamp"].world.clock.now() > state["burnt"] + 200:
            state["new"] = True
            peers["lamp"].world.lamp.replace()
    ev, _ = suspenders_run(tmp_path, inject, campaign)
    kinds = [e["event"] for e in ev]
    assert "failed" not in kinds and "suspended" in kinds and "resumed" in kinds
    assert next(e for e in ev if e["event"] == "suspended")["device"] == "lamp"


def test_illuminance_jump_discards_and_retakes_the_points_since_the_last_reading(tmp_path):
    def step(peers):       # 1 % less current: within the current tolerance, 3.4 % less light
        lamp = peers["lamp"].world.lamp
        lamp.set_current(0.99 * lamp.current_setpoint_a(), 0.0)
    ev, _ = suspenders_run(tmp_path, at_point(6, step))
    discarded = next(e for e in ev if e["event"] == "points_discarded")
    assert discarded["reason"] == "illuminance jump" and len(discarded["point_ids"]) >= 1
    assert next(e for e in ev if e["event"] == "suspended")["device"] == "illuminance"


@pytest.mark.parametrize("peer", ["meter", "arm"])
def test_device_that_stops_answering_pauses_until_it_answers(tmp_path, peer):
    ev, _ = suspenders_run(tmp_path, at_point(6, lambda peers: peers[peer].inject("no_reply", count=6)))
    suspended = next(e for e in ev if e["event"] == "suspended")
    assert suspended["device"] in (peer, "arm_azimuth", "arm_polar") and "failed 3 times" in suspended["reason"]
    assert any(e["event"] == "resumed" for e in ev)


def test_lamp_error_queue_entry_is_reported_and_lamp_still_switched_off(tmp_path):
    status, _, runner, plan, lamp_on, moving = run(
        tmp_path, small_campaign(), inject=at_point(2, lambda peers: peers["lamp"].inject("error_queue")))
    assert not lamp_on and not moving
    kinds = [e["event"] for e in events(tmp_path / "ds")]
    assert status == "complete" and "device_errors" in kinds


def test_transient_camera_failure_is_retried_and_flagged(tmp_path):
    err = DeviceError("camera", "garbled reply", transient=True)
    status, _, runner, plan, lamp_on, moving = run(
        tmp_path, small_campaign(), camera_fault=lambda cam: FailingCapture(cam, at=10, error=err, persistent=False))
    assert status == "complete"
    got = rows(tmp_path / "ds")
    assert len(got) == len(plan.points)
    assert sum("retried" in r["flags"] for r in got) == 1
    assert [e for e in events(tmp_path / "ds") if e["event"] == "retry"][0]["device"] == "camera"


def test_interrupt_marks_status_and_makes_safe(tmp_path):
    status, _, runner, plan, lamp_on, moving = run(
        tmp_path, small_campaign(),
        camera_fault=lambda cam: FailingCapture(cam, at=15, error=KeyboardInterrupt(), persistent=False))
    assert status == "interrupted"
    manifest = json.loads((tmp_path / "ds" / "dataset.json").read_text())
    assert manifest["status"] == "interrupted"
    assert manifest["counts"]["measured"] == len(rows(tmp_path / "ds")) > 0
    assert not lamp_on and not moving


def test_images_are_written_when_asked(tmp_path):
    campaign = small_campaign(capture={"save_images": True},
                              incidence=[{"phi": 0, "theta": [30]}],
                              viewing=[{"points": [[20, 180], [40, 90]]}])
    status, _, runner, plan, lamp_on, moving = run(tmp_path, campaign)
    assert status == "complete"
    got = rows(tmp_path / "ds")
    for r in got:
        img, meta = read_luminance_exr(tmp_path / "ds" / "images" / f"{r['point_id']}.exr")
        assert img.shape == (1040, 1390) and img.dtype == np.float32
        x0, y0, w, h = meta["roi_window"]
        roi_mean = float(np.mean(img[y0:y0 + h, x0:x0 + w], dtype=np.float64))
        assert roi_mean == pytest.approx(float(r["luminance_cd_m2"]), rel=1e-5)
        assert meta["theta_o_deg"] == pytest.approx(float(r["theta_o_deg"]), abs=1e-12)
        # the lit spot is visible and bounded: dark corners, bright centre
        assert img[0, 0] < 0.01 * roi_mean and img[520, 695] > 0.5 * roi_mean


def test_cli_refuses_bad_campaign_without_writing(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    data = yaml.safe_load((ROOT / "campaigns" / "quick.yaml").read_text())
    data["incidence"][0]["theta"].append(91)
    bad.write_text(yaml.safe_dump(data))
    out = tmp_path / "out"
    assert main(["run", str(bad), "--out", str(out), "--quiet"]) == 2
    assert "incidence[0].theta[5]" in capsys.readouterr().err
    assert not out.exists()


def test_cli_refuses_existing_output(tmp_path, capsys):
    out = tmp_path / "out"
    out.mkdir()
    (out / "brdf.csv").write_text("keep me\n")
    assert main(["run", str(ROOT / "campaigns" / "quick.yaml"), "--out", str(out), "--quiet"]) == 2
    assert "already exists" in capsys.readouterr().err
    assert (out / "brdf.csv").read_text() == "keep me\n"


def test_cli_requires_simulated_brdf_on_simulated_rig(tmp_path, capsys):
    data = yaml.safe_load((ROOT / "campaigns" / "quick.yaml").read_text())
    del data["sample"]["simulated_brdf"]
    f = tmp_path / "c.yaml"
    f.write_text(yaml.safe_dump(data))
    assert main(["run", str(f), "--out", str(tmp_path / "o"), "--quiet"]) == 2
    assert "sample.simulated_brdf" in capsys.readouterr().err
    assert not (tmp_path / "o").exists()


def test_manifest_carries_campaign_and_truth(tmp_path):
    path = ROOT / "campaigns" / "quick.yaml"
    from rig.config.campaign import load_campaign
    m = manifest_for(load_campaign(path), path, RigConfig())
    assert m["campaign"]["content"]["name"] == "quick"
    assert m["simulated_brdf"]["params"]["n"] == 24.0
    assert m["rig"]["simulated"] is True
    assert "simulated_brdf" not in m["sample"]


def test_runner_never_moves_through_a_forbidden_zone(tmp_path):
    from rig.acquisition.moves import CollisionError
    from rig.config.zones import CollisionsConfig, ForbiddenZone
    zone = ForbiddenZone(name="lamp_lever", description="test", arm_azimuth=(40.0, 50.0), arm_polar=(-10.0, 10.0))
    rig_cfg = RigConfig(collisions=CollisionsConfig(zones=[zone]))
    campaign = small_campaign()
    writer = DatasetWriter(tmp_path / "ds", {})
    with SimulatedRig(rig_cfg, "lambert", {"kd": 0.5}) as sim:
        runner = Runner(campaign, build_plan(campaign, rig_cfg), sim.devices, writer, rig_cfg)
        with pytest.raises(CollisionError, match="forbidden zone 'lamp_lever'"):
            runner.mover.move((0.0, 0.0, 90.0, 0.0))     # the arm would sweep through the lever
        assert all(abs(ax.position_deg()) < 0.01 for ax in sim.devices.arm.axes)    # nothing moved
        runner.mover.move((0.0, 0.0, 90.0, 30.0))        # a path beside it is fine... if it stays clear
    writer.close()


def test_next_move_starts_before_the_point_is_merged_and_written(tmp_path, monkeypatch):
    """Merging (a second for a full frame) and writing overlap the move to the next point."""
    from rig.acquisition.capture import Acquisition  # the raw path's acquisition reduces (merges) itself
    log = []
    reduce = Acquisition.reduce
    monkeypatch.setattr(Acquisition, "reduce", lambda acq: (log.append("merge"), reduce(acq))[1])
    campaign = small_campaign()
    rig_cfg = RigConfig()
    writer = DatasetWriter(tmp_path / "ds", {})
    with SimulatedRig(rig_cfg, "lambert", {"kd": 0.5}) as sim:
        arm_azimuth = sim.devices.arm.axes[0]
        start = arm_azimuth.start_move
        monkeypatch.setattr(arm_azimuth, "start_move", lambda deg: (log.append("move"), start(deg))[1])
        assert Runner(campaign, build_plan(campaign, rig_cfg), sim.devices, writer, rig_cfg).run() == "complete"
        sim.world.clock.sleep(1.0)
        assert not any(ax.is_moving() for ax in (*sim.devices.stage.axes, *sim.devices.arm.axes))
    writer.close()
    merges = [k for k, what in enumerate(log) if what == "merge"]
    assert len(merges) == 16
    # every merge but the last is preceded directly by the start of the next move
    assert all(log[k - 1] == "move" for k in merges[:-1])
    assert sorted(r["point_id"] for r in rows(tmp_path / "ds")) == sorted(p.point_id for p in build_plan(
        campaign, rig_cfg).points)
