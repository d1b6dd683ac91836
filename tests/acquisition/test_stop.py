"""Stopping a run from any state, and the exits that must always end (issue 9, defects 3 and 9).

In-process runs use a paced simulated clock (RIG_SIM_PACE: one rig second takes PACE wall
seconds), so that another thread can ask for a stop while the runner is inside a long wait,
as a Ctrl+C would; every assertion on time is on rig time. The `rig run` tests signal a real
process, as tests/acquisition/test_resume.py does.
"""

from __future__ import annotations

import csv
import json
import math
import os
import random
import signal
import subprocess
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml

from repo_paths import ROOT
from rig.acquisition.engine import Runner
from rig.acquisition.run import run_campaign
from rig.acquisition.suspenders import IlluminanceJump
from rig.config.campaign import Campaign, parse_campaign
from rig.config.rigfile import RigConfig
from rig.core.errors import DeviceError
from rig.core.values import Progress
from rig.data.dataset_writer import DatasetWriter
from rig.drivers.interfaces import RigDevices
from rig.drivers.wallclock import WallClock
from rig.planning.plan import build_plan
from rig.session.connect import open_campaign_rig
from rig.simulators.clock import SimClock
from rig.simulators.rig import SimulatedRig
from rig_process import events_text, start_rig, wait_until

CAMPAIGN = ROOT / "tests" / "campaigns" / "e2e-reduced.yaml"
#: Wall seconds per rig second of the paced runs: a 300 s warm-up lasts 0.6 s.
PACE = 0.002
#: Rig time a wait may take to notice a stop (its slice, plus one meter reading in flight).
STOP_LATENCY_S = 2.0


def campaign(**extra) -> Campaign:
    """Two series of eight views each, a short warm-up; `extra` replaces top-level keys."""
    data = {
        "name": "stop",
        "sample": {"id": "S", "simulated_brdf": {"model": "lambert", "params": {"kd": 0.5}}},
        "incidence": [{"phi": 0, "theta": [0, 40]}],
        "viewing": [{"centred_on": "normal", "theta": [15, 35], "phi": [0, 90, 180, 270]}],
        "lamp": {"warmup_min_s": 300},
        **extra,
    }
    return parse_campaign(data)


def with_settings(c: Campaign, **sections: dict) -> Campaign:
    """`c` with section fields replaced without validation (values the validator would refuse)."""
    return c.model_copy(update={name: getattr(c, name).model_copy(update=fields) for name, fields in sections.items()})


@dataclass
class Ended:
    status: str
    error: BaseException | None
    runner: Runner
    requested_rig_s: float | None     # rig time (runner's origin) when the other thread asked to stop
    lamp_on: bool
    moving: list[str]
    folder: Path

    def events(self) -> list[dict]:
        return [json.loads(line) for line in (self.folder / "events.jsonl").read_text().splitlines()]

    def kinds(self) -> list[str]:
        return [e["event"] for e in self.events()]

    def first(self, kind: str) -> dict:
        return next(e for e in self.events() if e["event"] == kind)

    def rows(self) -> list[str]:
        return (self.folder / "brdf.csv").read_text().splitlines()[1:]

    def manifest(self) -> dict:
        return json.loads((self.folder / "dataset.json").read_text())


def run(tmp_path: Path, c: Campaign, *, stop_when: Callable[[Progress], bool] | None = None,
        on_progress: Callable[[dict, Runner, Progress], None] | None = None, delay_s: float = 0.02) -> Ended:
    """Run `c` on the simulated rig; once `stop_when(progress)` holds, another thread waits
    `delay_s` of wall time and asks for a graceful stop. `on_progress(peers, runner, p)` runs
    in the runner's thread at every report (fault injection)."""
    rig = RigConfig()
    writer = DatasetWriter(tmp_path / "ds", {"campaign": {"name": c.name}})
    in_state = threading.Event()
    requested: list[float] = []
    with SimulatedRig(rig, "lambert", {"kd": 0.5}) as sim:
        def progress(p: Progress) -> None:
            if on_progress is not None:
                on_progress(sim.peers, runner, p)
            if stop_when is not None and stop_when(p):
                in_state.set()
        runner = Runner(c, build_plan(c, rig), sim.devices, writer, rig, progress=progress)

        def stopper() -> None:
            if in_state.wait(timeout=60):
                time.sleep(delay_s)
                requested.append(sim.world.clock.now() - runner.t0)
                runner.request_stop("test")
        thread = threading.Thread(target=stopper, daemon=True)
        thread.start()
        try:
            status, error = runner.run(), None
        except Exception as exc:
            status, error = "raised", exc
        in_state.set()
        thread.join(timeout=10)
        sim.world.clock.sleep(1.0)        # a stopped axis settles; one still running would not be done
        moving = [ax.name for ax in (*sim.devices.stage.axes, *sim.devices.arm.axes) if ax.is_moving()]
        lamp_on = sim.world.lamp.output_on
    writer.close()
    return Ended(status, error, runner, requested[0] if requested else None, lamp_on, moving, tmp_path / "ds")


@pytest.fixture
def paced(monkeypatch):
    monkeypatch.setenv("RIG_SIM_PACE", str(PACE))


def assert_stopped_cleanly(end: Ended, latency_s: float = STOP_LATENCY_S) -> None:
    """`interrupted` within `latency_s` of rig time after the request, parked, lamp off, axes still, completed
    points kept."""
    assert end.status == "interrupted", end.error
    assert end.requested_rig_s is not None
    honoured = end.first("stop_requested")["rig_time_s"]
    assert 0 <= honoured - end.requested_rig_s <= latency_s
    kinds = end.kinds()
    assert kinds.index("stop_requested") < kinds.index("parked")
    assert end.first("interrupted")["graceful"] is True
    assert kinds[-1] == "safe_state" and end.events()[-1]["lamp_off"]
    assert not end.lamp_on and not end.moving
    m = end.manifest()
    assert m["status"] == "interrupted"
    assert m["counts"]["measured"] == len(end.rows()) == end.runner.measured


def test_stop_during_warm_up_ends_within_a_second_of_rig_time(tmp_path, paced):
    end = run(tmp_path, campaign(), stop_when=lambda p: p.message.startswith("lamp warm-up"))
    assert_stopped_cleanly(end)
    kinds = end.kinds()
    assert "warmup_stable" not in kinds and "point_pending" not in kinds and "illuminance" not in kinds
    assert end.first("stop_requested")["rig_time_s"] < 300        # the warm-up was not waited out
    assert end.rows() == []


def test_stop_while_paused_for_a_burnt_lamp_skips_the_closing_reading(tmp_path, paced):
    burnt = []

    def burn_out_after_five(peers, runner, p):
        if p.done == 5 and not burnt:
            burnt.append(p.rig_time_s)
            peers["lamp"].inject("burnout")
    end = run(tmp_path, campaign(suspenders={"max_wait_s": 1800}), on_progress=burn_out_after_five,
              stop_when=lambda p: p.message.startswith("PAUSED (lamp)"))
    assert_stopped_cleanly(end)
    kinds = end.kinds()
    assert kinds.index("suspended") < kinds.index("stop_requested") and "resumed" not in kinds
    assert end.first("stop_requested")["rig_time_s"] < end.first("suspended")["rig_time_s"] + 1800
    assert "illuminance" not in kinds[kinds.index("stop_requested"):]   # no light to read: no closing reading
    # the points since the last passing lamp check may have been dark: discarded, no row measured after the burn-out
    with open(end.folder / "brdf.csv", newline="") as fh:
        measured_s = [float(r["rig_time_s"]) for r in csv.DictReader(fh)]
    assert len(measured_s) <= 5 and all(t < burnt[0] for t in measured_s)


def test_stop_while_waiting_for_the_illuminance_to_settle(tmp_path, paced):
    """An E⊥ jump pauses the run until two readings warmup_check_s apart agree; here they never do."""
    stepped = []

    def step_current(peers, runner, p):      # 1 % less current: 3.4 % less light, within the current tolerance
        if p.done == 3 and not stepped:
            stepped.append(True)
            lamp = peers["lamp"].world.lamp
            lamp.set_current(0.99 * lamp.current_setpoint_a(), 0.0)
    c = with_settings(campaign(lamp={"warmup_min_s": 60, "warmup_max_s": 120}), lamp={"warmup_stable_rel": 1e-12})
    end = run(tmp_path, c, on_progress=step_current, stop_when=lambda p: p.message.startswith("PAUSED (illuminance)"))
    assert_stopped_cleanly(end)
    assert end.first("suspended")["device"] == "illuminance" and "resumed" not in end.kinds()
    assert end.first("points_discarded")["reason"] == "illuminance jump"


def test_stop_mid_series_finishes_the_point_in_flight_then_brackets_and_parks(tmp_path, paced):
    end = run(tmp_path, campaign(), stop_when=lambda p: p.done >= 4)
    assert_stopped_cleanly(end, latency_s=math.inf)     # a point in flight is finished: up to 3 rig s here, bounded
    events = end.events()                                # below as at most one point measured after the request
    pending = [e["row"] for e in events if e["event"] == "point_pending"]
    assert len(pending) >= 4
    assert sum(row["rig_time_s"] > end.requested_rig_s for row in pending) <= 1   # at most the one in flight
    kinds = end.kinds()
    after_stop = kinds[kinds.index("stop_requested"):]
    assert after_stop.index("illuminance") < after_stop.index("parked")      # the closing E⊥ reading
    assert "pending_without_closing_reading" not in kinds
    assert len(end.rows()) == len(pending)


def test_stop_during_the_alignment_scan_ends_it_before_the_next_step(tmp_path):
    """Ctrl+C in the specular-peak alignment (a 7 × 7 scan: tens of rig seconds of moves and captures; minutes on
    hardware) is honoured before the next step, not once the scan is done (issue 30); then parked, lamp off, axes
    still. The request is made as the SIGINT handler makes it (`request_stop`), as step 10 begins."""
    asked: list[float] = []

    def ctrl_c_at_step_10(peers, runner, p):
        if p.message.endswith("step 10 of 51") and not asked:
            asked.append(p.rig_time_s)
            runner.request_stop("SIGINT")
    end = run(tmp_path, campaign(alignment={"theta_i_deg": 40, "steps": 7}), on_progress=ctrl_c_at_step_10)
    assert end.status == "interrupted", end.error
    ev = end.events()
    stops = [e for e in ev if e["event"] == "stop_requested"]
    assert len(stops) == 1 and stops[0]["rig_time_s"] == pytest.approx(asked[0], abs=1e-6)    # not one step more
    kinds = end.kinds()
    assert "alignment_scan" not in kinds and "aligned" not in kinds and "illuminance" not in kinds
    assert kinds.index("stop_requested") < kinds.index("parked") and end.first("interrupted")["graceful"] is True
    assert kinds[-1] == "safe_state" and ev[-1]["lamp_off"] and not end.lamp_on and not end.moving
    assert "alignment" not in end.manifest() and end.rows() == []      # a resumed run scans again


def test_second_request_stops_the_axes_inside_the_park(tmp_path):
    """Ctrl+C again while parking: the move is cut short, no `parked`, lamp off, axes still."""
    def abort_when_parking(peers, runner, p):
        if p.done == 3:
            runner.request_stop("first Ctrl+C")
        if p.message == "parking":
            runner.request_abort("second Ctrl+C")
    end = run(tmp_path, campaign(), on_progress=abort_when_parking)
    assert end.status == "interrupted"
    kinds = end.kinds()
    assert "stop_requested" in kinds and "parked" not in kinds
    interrupted = end.first("interrupted")
    assert interrupted["graceful"] is False and interrupted["reason"] == "second Ctrl+C"
    assert kinds[-1] == "safe_state" and end.events()[-1]["lamp_off"]
    assert not end.lamp_on and not end.moving
    assert end.manifest()["counts"]["measured"] == len(end.rows()) == 3


def test_a_drift_limit_below_the_meter_noise_fails_after_a_bounded_number_of_retakes(tmp_path):
    """Built without validation (it refuses such a limit): the runner must still end."""
    c = with_settings(campaign(lamp={"warmup_stable_rel": 0.05}), suspenders={"illuminance_drift_limit_rel": 1e-7})
    pauses = []

    def never_ending(peers, runner, p):
        if p.message.startswith("PAUSED (illuminance): "):
            pauses.append(p.rig_time_s)
            if len(pauses) > 50:
                raise RuntimeError("re-takes never end")
    end = run(tmp_path, c, on_progress=never_ending)
    assert end.status == "raised" and isinstance(end.error, DeviceError), end.error
    message = str(end.error)
    assert "suspenders.illuminance_drift_limit_rel = 1e-07" in message and "raise the limit" in message
    discards = [e for e in end.events() if e["event"] == "points_discarded"]
    first = discards[0]["point_ids"][0]
    assert sum(first in e["point_ids"] for e in discards) == IlluminanceJump.max_retakes + 1
    assert not end.lamp_on and not end.moving
    m = end.manifest()
    assert m["status"] == "failed" and "illuminance_drift_limit_rel" in m["error"]
    assert m["counts"]["measured"] == len(end.rows())


def test_max_wait_bounds_the_whole_pause_including_its_checks(tmp_path):
    """Each unsteadiness check itself takes warmup_check_s (60 s); the pause may not last 3 × max_wait_s."""
    c = with_settings(campaign(lamp={"warmup_min_s": 60, "warmup_max_s": 120},
                               suspenders={"max_wait_s": 300, "check_interval_s": 30}),
                      suspenders={"illuminance_drift_limit_rel": 1e-7}, lamp={"warmup_stable_rel": 1e-12})
    end = run(tmp_path, c)
    assert end.status == "raised" and str(end.error).startswith("illuminance: paused")
    paused = end.first("suspend_timeout")["rig_time_s"] - end.first("suspended")["rig_time_s"]
    assert 300 <= paused <= 300 + 60 + 1          # at most one check beyond max_wait_s
    assert not end.lamp_on and not end.moving


def test_signals_landing_in_the_exit_path_cannot_cut_it_short(tmp_path, monkeypatch):
    """Ctrl+C again and SIGTERM delivered just as the rig is being made safe (the 1-in-11 case of two
    quick Ctrl+C): the exit path still switches the lamp off, stops the axes and writes the status."""
    original = RigDevices.safe_state
    lamp_was_on: list[bool] = []

    def signalled_safe_state(devices: RigDevices) -> list[str]:
        for sig in (signal.SIGINT, signal.SIGTERM):
            os.kill(os.getpid(), sig)
        lamp_was_on.append(devices.lamp.output_is_on())
        problems = original(devices)
        lamp_was_on.append(devices.lamp.output_is_on())
        return problems
    monkeypatch.setattr(RigDevices, "safe_state", signalled_safe_state)
    sent = []

    def first_ctrl_c(p: Progress) -> None:
        if p.done == 3 and not sent:
            sent.append(p.done)
            os.kill(os.getpid(), signal.SIGINT)
    c, rig = campaign(), RigConfig()
    handler = signal.getsignal(signal.SIGINT)
    outcome = run_campaign(c, rig, tmp_path / "ds", open_campaign_rig, progress=first_ctrl_c, handle_signals=True)
    assert signal.getsignal(signal.SIGINT) is handler               # restored afterwards
    assert outcome.status == "interrupted" and lamp_was_on == [True, False]
    folder = tmp_path / "ds"
    ev = [json.loads(line) for line in (folder / "events.jsonl").read_text().splitlines()]
    assert ev[-1]["event"] == "safe_state" and ev[-1]["lamp_off"]
    assert "parked" in [e["event"] for e in ev]                      # the graceful stop had finished
    m = json.loads((folder / "dataset.json").read_text())
    assert m["status"] == "interrupted"
    assert m["counts"]["measured"] == len((folder / "brdf.csv").read_text().splitlines()) - 1 >= 3


class Abort(BaseException):
    pass


def abort_on_call(n: int) -> Callable[[], None]:
    """A sleep check that raises at its n-th call."""
    calls = []

    def check() -> None:
        calls.append(None)
        if len(calls) >= n:
            raise Abort
    return check


@pytest.mark.parametrize("make_clock", [WallClock, lambda: SimClock(pace=0.1)], ids=["wall", "paced-sim"])
def test_a_clock_sleep_can_be_cut_short_by_its_check(make_clock):
    """Sleeps are sliced: a long wait looks at the check again and again, and ends when it raises."""
    clock = make_clock()
    clock.sleep_check = abort_on_call(3)
    with pytest.raises(Abort):
        clock.sleep(2.0)


def test_an_unpaced_sim_clock_checks_once_per_sleep():
    clock = SimClock(pace=0.0)
    clock.sleep_check = abort_on_call(1)
    with pytest.raises(Abort):
        clock.sleep(3600.0)
    assert clock.now() == pytest.approx(0.0, abs=0.0)     # nothing elapsed: the check comes first


@pytest.mark.parametrize("value", ["-1", "fast", "nan", "inf"])
def test_a_bad_pace_in_the_environment_is_refused_naming_the_variable(monkeypatch, value):
    monkeypatch.setenv("RIG_SIM_PACE", value)
    with pytest.raises(ValueError, match="RIG_SIM_PACE"):
        SimClock()


# -- through `rig run` ------------------------------------------------------------------------------

def rig_run(campaign_file: Path, out: Path, **env: str) -> subprocess.Popen:
    return start_rig("run", str(campaign_file), "--out", str(out), "--quiet", env=env)


def events_of(folder: Path) -> list[dict]:
    lines = (folder / "events.jsonl").read_text().splitlines()
    return [json.loads(line) for line in lines]


def wait_for(proc: subprocess.Popen, folder: Path, ready: Callable[[str], bool], what: str) -> None:
    """Poll events.jsonl until `ready(text)`; fail if the run ends or hangs first."""
    wait_until(lambda: ready(events_text(folder)), proc, what)


def test_rig_run_sigint_during_warm_up(tmp_path):
    data = yaml.safe_load(CAMPAIGN.read_text())
    data["lamp"] = {"warmup_min_s": 3000}              # 6 s of wall time at the pace below
    f = tmp_path / "long-warm-up.yaml"
    f.write_text(yaml.safe_dump(data))
    out = tmp_path / "ds"
    proc = rig_run(f, out, RIG_SIM_PACE=str(PACE))
    wait_for(proc, out, lambda text: '"lamp_on"' in text, "the warm-up")
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=60) == 130, proc.stderr.read()
    ev = events_of(out)
    kinds = [e["event"] for e in ev]
    assert "point_pending" not in kinds and "warmup_stable" not in kinds
    lamp_on = next(e for e in ev if e["event"] == "lamp_on")["rig_time_s"]
    assert next(e for e in ev if e["event"] == "stop_requested")["rig_time_s"] < lamp_on + 3000
    assert "parked" in kinds and kinds[-1] == "safe_state" and ev[-1]["lamp_off"]
    assert json.loads((out / "dataset.json").read_text())["status"] == "interrupted"


def test_rig_run_sigint_during_the_alignment_scan(tmp_path):
    """A real SIGINT once the warm-up is over, while the arm scans for the specular peak (a 9 × 9 scan: about
    40 rig seconds, over a second of wall time at the pace below): the scan ends unfinished, exit 130, parked,
    lamp off."""
    data = yaml.safe_load(CAMPAIGN.read_text())
    data["lamp"] = {"warmup_min_s": 0, "warmup_check_s": 1, "warmup_stable_rel": 0.05}
    data["alignment"] = {"theta_i_deg": 40, "steps": 9}
    f = tmp_path / "aligned.yaml"
    f.write_text(yaml.safe_dump(data))
    out = tmp_path / "ds"
    proc = rig_run(f, out, RIG_SIM_PACE="0.03")
    wait_for(proc, out, lambda text: '"warmup_stable"' in text, "the end of the warm-up")
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=60) == 130, proc.stderr.read()
    kinds = [e["event"] for e in events_of(out)]
    assert "stop_requested" in kinds and "alignment_scan" not in kinds and "aligned" not in kinds
    assert "parked" in kinds and kinds[-1] == "safe_state" and events_of(out)[-1]["lamp_off"]
    assert json.loads((out / "dataset.json").read_text())["status"] == "interrupted"


def _two_signals_cases() -> list:
    """Random delays, and the moment the exit path starts (just after `parked`)."""
    rnd = random.Random(20261123)
    return [*(pytest.param(signal.SIGINT, f"{rnd.uniform(0, 0.02):.4f}", id=f"random-delay-{k}") for k in range(2)),
            pytest.param(signal.SIGTERM, '"parked"', id="sigterm-when-cleanup-starts")]


@pytest.mark.parametrize("second, when", _two_signals_cases())
def test_rig_run_two_quick_signals_always_end_interrupted_and_safe(tmp_path, second, when):
    """Ctrl+C, then Ctrl+C (or SIGTERM) after a delay (s) or once an event is on disk."""
    out = tmp_path / "ds"
    proc = rig_run(CAMPAIGN, out)
    wait_for(proc, out, lambda text: text.count('"point_pending"') >= 3, "3 points")
    proc.send_signal(signal.SIGINT)
    if when.startswith('"'):
        wait_for(proc, out, lambda text: when in text or '"safe_state"' in text, when)
    else:
        time.sleep(float(when))
    if proc.poll() is None:
        proc.send_signal(second)
    assert proc.wait(timeout=60) == 130, proc.stderr.read()
    ev = events_of(out)
    assert ev[-1]["event"] == "safe_state" and ev[-1]["lamp_off"]
    m = json.loads((out / "dataset.json").read_text())
    assert m["status"] == "interrupted"
    assert m["counts"]["measured"] == len((out / "brdf.csv").read_text().splitlines()) - 1
