"""Run engine exits: completed points are kept, lamp off and axes stopped on every path."""

import csv
import json
from pathlib import Path

import numpy as np
import pytest
import yaml

from drivers.interfaces import DeviceError
from rig.campaign import parse_campaign
from rig.cli import main, manifest_for
from rig.dataset import DatasetWriter
from rig.images import read_luminance_exr
from rig.plan import build_plan
from rig.rigconfig import RigConfig
from rig.runner import Runner
from simulators.rig import build_simulated_rig

ROOT = Path(__file__).resolve().parents[1]


def small_campaign(**extra):
    data = {
        "name": "small",
        "sample": {"id": "S", "simulated_brdf": {"model": "lambert", "params": {"kd": 0.5}}},
        "incidence": [{"phi": 0, "theta": [0, 60]}],
        "viewing": [{"centred_on": "normal", "theta": [10, 30], "phi": [0, 90, 180, 270]}],
        "lamp": {"warmup_min_s": 60},
        **extra,
    }
    return parse_campaign(data)


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


def run(tmp_path, campaign, fault=None):
    rig = RigConfig()
    plan = build_plan(campaign, rig)
    truth = campaign.sample.simulated_brdf
    devices, world = build_simulated_rig(rig, truth.model, truth.params)
    if fault is not None:
        devices.camera = fault(devices.camera)
    writer = DatasetWriter(tmp_path / "ds", {"campaign": {"name": campaign.name}})
    runner = Runner(campaign, plan, devices, writer, rig)
    try:
        status = runner.run()
        error = None
    except Exception as exc:
        status, error = "raised", exc
    writer.close()
    return status, error, runner, world, plan


def rows(folder):
    with open(folder / "brdf.csv", newline="") as fh:
        return list(csv.DictReader(fh))


def events(folder):
    return [json.loads(l) for l in (folder / "events.jsonl").read_text().splitlines()]


def test_complete_run_switches_lamp_off(tmp_path):
    status, _, runner, world, plan = run(tmp_path, small_campaign())
    assert status == "complete"
    assert not world.lamp.output_on
    assert not any(ax.is_moving() for ax in (*runner.dev.stage.axes, *runner.dev.arm.axes))
    assert len(rows(tmp_path / "ds")) == len(plan.points) == 16


def test_persistent_device_failure_keeps_points_and_makes_safe(tmp_path):
    err = DeviceError("camera", "no answer after 3 s", transient=False)
    status, error, runner, world, plan = run(
        tmp_path, small_campaign(), lambda cam: FailingCapture(cam, at=20, error=err, persistent=True))
    assert status == "raised" and error is err
    kept = rows(tmp_path / "ds")
    assert 0 < len(kept) < len(plan.points) and len(kept) == runner.measured
    manifest = json.loads((tmp_path / "ds" / "dataset.json").read_text())
    assert manifest["status"] == "failed" and "camera: no answer" in manifest["error"]
    assert manifest["counts"]["measured"] == len(kept)
    assert not world.lamp.output_on
    ev = events(tmp_path / "ds")
    assert ev[-2]["event"] == "failed" and ev[-1]["event"] == "safe_state" and ev[-1]["lamp_off"]


def test_transient_failure_is_retried_and_flagged(tmp_path):
    err = DeviceError("camera", "garbled reply", transient=True)
    status, _, runner, world, plan = run(
        tmp_path, small_campaign(), lambda cam: FailingCapture(cam, at=10, error=err, persistent=False))
    assert status == "complete"
    got = rows(tmp_path / "ds")
    assert len(got) == len(plan.points)
    assert sum("retried" in r["flags"] for r in got) == 1
    assert [e for e in events(tmp_path / "ds") if e["event"] == "retry"][0]["device"] == "camera"


def test_interrupt_marks_status_and_makes_safe(tmp_path):
    status, _, runner, world, plan = run(
        tmp_path, small_campaign(),
        lambda cam: FailingCapture(cam, at=15, error=KeyboardInterrupt(), persistent=False))
    assert status == "interrupted"
    manifest = json.loads((tmp_path / "ds" / "dataset.json").read_text())
    assert manifest["status"] == "interrupted"
    assert manifest["counts"]["measured"] == len(rows(tmp_path / "ds")) > 0
    assert not world.lamp.output_on


def test_images_are_written_when_asked(tmp_path):
    campaign = small_campaign(capture={"save_images": True},
                              incidence=[{"phi": 0, "theta": [30]}],
                              viewing=[{"points": [[20, 180], [40, 90]]}])
    status, _, runner, world, plan = run(tmp_path, campaign)
    assert status == "complete"
    got = rows(tmp_path / "ds")
    for r in got:
        img, meta = read_luminance_exr(tmp_path / "ds" / "images" / f"{r['point_id']}.exr")
        assert img.shape == (1040, 1390) and img.dtype == np.float32
        x0, y0, w, h = meta["roi_window"]
        roi_mean = float(np.mean(img[y0:y0 + h, x0:x0 + w], dtype=np.float64))
        assert roi_mean == pytest.approx(float(r["luminance_cd_m2"]), rel=1e-5)
        assert meta["theta_o_deg"] == float(r["theta_o_deg"])
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
    from rig.campaign import load_campaign
    m = manifest_for(load_campaign(path), path, RigConfig())
    assert m["campaign"]["content"]["name"] == "quick"
    assert m["simulated_brdf"]["params"]["n"] == 24.0
    assert m["rig"]["simulated"] is True
    assert "simulated_brdf" not in m["sample"]
