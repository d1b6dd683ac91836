"""The lamp supply's watchdog stays fed through every run of blocking exchanges (issue 30, item 1).

The supply's keep-alive runs only when the rig clock is given the chance (rig.acquisition.tending). Before the fix
one E⊥ measurement read the meter `illuminance.readings` times in a row without it: on the simulated rig
(watchdog 5 s) 25 readings of 0.2 s, or 5 readings of 1 s, let the watchdog switch the lamp off during the first
E⊥, and the run waited for a "burnt out" lamp and failed with 0 points. A camera whose frames block (a vendor
camera: no sleep on the rig clock) starved it the same way over one point's frames and darks. What cannot be fed, a
single blocking exchange beyond the budget, is refused before anything starts (rig.config.watchdog).
"""

from __future__ import annotations

import csv
import json
import threading
from pathlib import Path

import pytest
import yaml

from repo_paths import CAMPAIGNS, RIGS
from rig.acquisition.capturer import capturer_for
from rig.acquisition.engine import Runner
from rig.cli.main import main
from rig.config.campaign import CampaignError, Capture, check_campaign_for_rig, load_campaign, parse_campaign
from rig.config.rigfile import load_rig_config, simulated_rig
from rig.config.watchdog import hdr_picture_s
from rig.core.values import Frame, Window
from rig.data.dataset_writer import DatasetWriter
from rig.drivers.interfaces import CalibratedLuminanceCamera
from rig.planning.plan import build_plan
from rig.simulators.clock import SimClock
from rig.simulators.rig import SimulatedRig


def rig_run(tmp_path: Path, *, campaign: dict | None = None, rig: dict | None = None) -> tuple[int, Path]:
    """`rig run` of campaigns/quick.yaml with `campaign`'s sections replaced, on the built-in rig spelt out
    (campaigns/rigs/simulated.yaml) with `rig`'s sections updated; a pause gives up after a minute of rig time."""
    data = {**yaml.safe_load((CAMPAIGNS / "quick.yaml").read_text()), "suspenders": {"max_wait_s": 60},
            **(campaign or {})}
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(data))
    rig_data = yaml.safe_load((RIGS / "simulated.yaml").read_text())
    for section, fields in (rig or {}).items():
        rig_data[section] = {**rig_data.get(section, {}), **fields}
    (tmp_path / "rig.yaml").write_text(yaml.safe_dump(rig_data))
    out = tmp_path / "out"
    return main(["run", str(tmp_path / "c.yaml"), "--rig", str(tmp_path / "rig.yaml"), "--out", str(out),
                 "--quiet"]), out


def events(folder: Path) -> list[dict]:
    return [json.loads(line) for line in (folder / "events.jsonl").read_text().splitlines()]


def assert_fed_throughout(out: Path, readings: int) -> None:
    """Every point measured, every E⊥ from `readings` readings, and the watchdog never expired."""
    ev = events(out)
    kinds = {e["event"] for e in ev}
    assert not {"watchdog_expired", "watchdog_off", "suspended"} & kinds
    assert {e["readings"] for e in ev if e["event"] == "illuminance"} == {readings}
    with open(out / "brdf.csv", newline="") as fh:
        kept = list(csv.DictReader(fh))
    assert len(kept) == json.loads((out / "dataset.json").read_text())["counts"]["measured"] > 0


def test_25_meter_readings_per_illuminance_keep_the_lamp_on(tmp_path):
    code, out = rig_run(tmp_path, campaign={"illuminance": {"readings": 25}})
    assert code == 0
    assert_fed_throughout(out, 25)


def test_one_second_meter_integrations_keep_the_lamp_on(tmp_path):
    code, out = rig_run(tmp_path, rig={"meter": {"integration_s": 1.0}})
    assert code == 0
    assert_fed_throughout(out, 5)


class BlockingCamera:
    """The simulated camera as a vendor camera behaves: a frame blocks its caller for the exposure and read-out
    (the rig time passes inside the device, `SimWorld.spend_s`), with no sleep on the rig clock."""

    def __init__(self, sim: SimulatedRig):
        self._camera, self._world = sim.devices.camera, sim.world
        self.exposed_s = 0.0

    def __getattr__(self, name):
        return getattr(self._camera, name)

    def _blocking(self, exposure_s: float, window: Window | None, dark: bool) -> Frame:
        frame, duration_s = self._camera.render(exposure_s, window, dark)
        self._world.spend_s(duration_s)
        self.exposed_s += duration_s
        return frame

    def capture(self, exposure_s, window=None):
        return self._blocking(exposure_s, window, dark=False)

    def capture_dark(self, exposure_s, window=None):
        return self._blocking(exposure_s, window, dark=True)


def test_a_point_of_blocking_frames_and_darks_keeps_the_lamp_on(tmp_path):
    """A dark sample: every frame is the longest exposure the rig file allows a vendor camera (half the watchdog),
    and one point takes a probe, frames and their darks: several watchdog periods of blocking exchanges."""
    rig = simulated_rig().model_copy(update={"camera": simulated_rig().camera.model_copy(
        update={"max_exposure_s": 2.5})})
    c = parse_campaign({
        "name": "dark", "sample": {"id": "S", "simulated_brdf": {"model": "lambert", "params": {"kd": 0.0005}}},
        "incidence": [{"phi": 0, "theta": [30]}], "viewing": [{"points": [[20, 180]]}],
        "lamp": {"warmup_min_s": 60}, "suspenders": {"max_wait_s": 60},
        "capture": {"mode": "fixed_bracket", "bracket_count": 2, "frames_per_exposure": 2, "max_frames": 4}})
    writer = DatasetWriter(tmp_path / "ds", {"campaign": {"name": c.name}})
    with SimulatedRig(rig, "lambert", {"kd": 0.0005}) as sim:
        camera = sim.devices.camera = BlockingCamera(sim)
        status = Runner(c, build_plan(c, rig), sim.devices, writer, rig).run()
        lamp_on = sim.world.lamp.output_on
    writer.close()
    assert camera.exposed_s > 2 * rig.lamp.watchdog_s        # the case is real: blocked for several periods
    assert status == "complete" and not lamp_on
    assert not {"watchdog_expired", "suspended"} & {e["event"] for e in events(tmp_path / "ds")}


class FakeCalibratedCamera(CalibratedLuminanceCamera):
    """A camera that calibrates its own pictures (as the LMK): every call blocks for `block_s` inside the device."""

    def __init__(self, clock, block_s: float):
        self.clock, self.block_s = clock, block_s
        self.sensor = simulated_rig().camera.sensor_info()

    def identity(self):
        return "fake LMK"

    def capture_luminance(self, exposure_s, window=None):
        self.clock.advance(self.block_s)
        return "picture"

    def capture_hdr_luminance(self, max_exposure_s, min_exposure_s, factor, window=None):
        return self.capture_luminance(max_exposure_s, window)


def test_a_calibrated_cameras_pictures_let_the_keep_alives_run_and_it_stays_one():
    """The LMK's metering series (up to four single pictures) is fed between pictures like a raw camera's frames,
    and the camera its capturer wraps is still a CalibratedLuminanceCamera, so its points take the calibrated path."""
    clock = SimClock()
    fed = []
    clock.keep_alive(1.0, lambda: fed.append(clock.now()))
    camera = capturer_for(FakeCalibratedCamera(clock, 0.6), Capture().settings(), clock).camera
    assert isinstance(camera, CalibratedLuminanceCamera) and camera.identity() == "fake LMK"
    assert [camera.capture_luminance(0.5) for _ in range(4)] == ["picture"] * 4
    assert fed == pytest.approx([1.2, 2.4])           # after the pictures that ended past a due time


class SlowSampler:
    """An adaptive campaign's source whose choice takes two seconds of rig time, as computing the next batch takes
    seconds of wall time on a real rig (there wall time is rig time), and returns only once the clock's keep-alives
    have had their chance meanwhile: a keep-alive of its own, due once the two seconds have passed, says so."""

    def __init__(self, clock):
        self.clock, self.fed, self.calls = clock, threading.Event(), 0
        clock.keep_alive(1.0, self.fed.set)

    def next_batch(self, rows, event):
        self.calls += 1
        self.fed.clear()
        self.clock.advance(2.0)                     # the computation's time: no keep-alive runs inside it
        if not self.fed.wait(timeout=5.0):           # hang guard: the keep-alive never got its chance
            raise AssertionError("no keep-alive ran while the next batch was computed")
        event("sampling_done", reason="test", batches=0, planned_rig_time_s=0.0)
        return []


def test_the_next_adaptive_batch_is_computed_while_the_keep_alives_run(tmp_path):
    c = parse_campaign({
        "name": "slow", "sample": {"id": "S", "simulated_brdf": {"model": "lambert", "params": {"kd": 0.5}}},
        "incidence": [{"phi": 0, "theta": [30]}], "viewing": [{"points": [[20, 180], [40, 90]]}],
        "lamp": {"warmup_min_s": 60}})
    rig = simulated_rig()
    writer = DatasetWriter(tmp_path / "ds", {"campaign": {"name": c.name}})
    with SimulatedRig(rig, "lambert", {"kd": 0.5}) as sim:
        source = SlowSampler(sim.world.clock)
        status = Runner(c, build_plan(c, rig), sim.devices, writer, rig, source=source).run()
    writer.close()
    assert status == "complete" and source.calls == 1
    ev = events(tmp_path / "ds")
    assert [e["reason"] for e in ev if e["event"] == "sampling_done"] == ["test"]     # its event, written after
    assert "watchdog_expired" not in {e["event"] for e in ev}


# -- what cannot be fed is refused before anything starts ------------------------------------------

def lmk_rig(tmp_path: Path, max_exposure_s: float) -> Path:
    """The example lab's rig (an LMK: one blocking call per HDR picture) on loopback addresses nothing
    ever connects to, with `max_exposure_s` and the default 5 s watchdog."""
    lab = yaml.safe_load((RIGS / "example-lab.yaml").read_text())
    for name, address in {"arm": "modbus-tcp://127.0.0.1:9", "stage": "modbus-tcp://127.0.0.1:9",
                          "lamp": "socket://127.0.0.1:9", "meter": "/dev/nonexistent-meter"}.items():
        lab["devices"][name]["address"] = address
    lab["camera"]["max_exposure_s"] = max_exposure_s
    lab["lamp"]["watchdog_s"] = 5.0
    path = tmp_path / "lmk.yaml"
    path.write_text(yaml.safe_dump(lab))
    return path


def test_an_hdr_picture_longer_than_the_watchdog_allows_is_refused_naming_the_keys(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["run", str(CAMPAIGNS / "quick.yaml"), "--rig", str(lmk_rig(tmp_path, 2.5)), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and not out.exists()
    for key in ("capture.max_exposures", "capture.bracket_stops", "camera.max_exposure_s", "lamp.watchdog_s"):
        assert key in err
    assert "2.5 s budget" in err and err.count("\n") == 2       # one message: the file's line and this one


def test_a_single_picture_or_a_shorter_hdr_series_fits(tmp_path):
    rig = load_rig_config(lmk_rig(tmp_path, 2.5))
    data = yaml.safe_load((CAMPAIGNS / "quick.yaml").read_text())
    check_campaign_for_rig(parse_campaign({**data, "capture": {"max_exposures": 1}}), rig)
    check_campaign_for_rig(parse_campaign(data), load_rig_config(lmk_rig(tmp_path, 1.0)))
    with pytest.raises(CampaignError, match="capture.bracket_step_stops"):
        check_campaign_for_rig(parse_campaign({**data, "capture": {"mode": "fixed_bracket"}}),
                               load_rig_config(lmk_rig(tmp_path, 1.0)))


def test_an_hdr_picture_takes_every_exposure_down_to_the_shortest():
    seconds, pictures = hdr_picture_s(4.0, 0.25, 2.0, 0.1)      # 4, 2, 1, 0.5, 0.25
    assert pictures == 5 and seconds == pytest.approx(7.75 + 0.5, rel=1e-12)
    assert hdr_picture_s(1.0, 1.0, 4.0, 0.0) == (pytest.approx(1.0), 1)


@pytest.mark.parametrize("campaign", sorted(CAMPAIGNS.glob("*.yaml")), ids=lambda p: p.stem)
def test_the_example_lab_runs_the_shipped_campaigns_within_its_watchdog(campaign):
    check_campaign_for_rig(load_campaign(campaign), load_rig_config(RIGS / "example-lab.yaml"), campaign)
