"""Bad input through the command line: one clear error (exit 2) naming what and where, nothing
moved (the rig is not even started), nothing written or overwritten."""

from pathlib import Path

import pytest
import yaml

from rig.cli import main

ROOT = Path(__file__).resolve().parents[1]
GOOD = yaml.safe_load((ROOT / "campaigns" / "quick.yaml").read_text())


def write(tmp_path, data=None, text=None) -> Path:
    f = tmp_path / "campaign.yaml"
    f.write_text(text if text is not None else yaml.safe_dump(data, sort_keys=False))
    return f


def with_(**changes):
    data = yaml.safe_load(yaml.safe_dump(GOOD))
    for key, value in changes.items():
        node, *path = key.split("__")
        target = data
        for part in [node, *path][:-1]:
            target = target[int(part)] if part.isdigit() else target[part]
        last = [node, *path][-1]
        target[int(last) if last.isdigit() else last] = value
    return data


CASES = {
    "malformed YAML": (dict(text="name: x\nsample: {id: [\n"), "not valid YAML at line"),
    "wrong type": (dict(data=with_(incidence__0__theta="eighty")), "incidence[0].theta"),
    "NaN": (dict(data=with_(incidence__0__theta=[float("nan")])), "finite"),
    "inf": (dict(data=with_(viewing__0__theta=[float("inf")])), "finite"),
    "out-of-range angle": (dict(data=with_(incidence__0__phi=400)), "incidence[0].phi"),
    "unknown key": (dict(data=with_(lamp__warmup_minutes=5)), "unknown key 'lamp.warmup_minutes'"),
    "unknown model": (dict(data=with_(sample__simulated_brdf__model="phong")), "sample.simulated_brdf.model"),
    "nothing reachable": (dict(data=with_(incidence=[{"phi": 0, "theta": [60]}],
                                          viewing=[{"points": [[60, 0], [88, 180]]}])), "no point of the campaign"),
    "bad schedule": (dict(data=with_(illuminance={"remeasure": "every_n_points"})), "needs `every` > 0"),
}


@pytest.mark.parametrize("name", sorted(CASES))
def test_bad_campaign(tmp_path, capsys, name):
    kwargs, expected = CASES[name]
    f = write(tmp_path, **kwargs)
    out = tmp_path / "out"
    assert main(["run", str(f), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rig: error: ") and str(f) in err and expected in err, err
    assert not out.exists()
    assert main(["plan", str(f)]) == 2 or name == "nothing reachable"   # plan only reports skipped points


def test_unwritable_output_folder(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["run", str(ROOT / "campaigns" / "quick.yaml"), "--out", str(blocker / "ds"), "--quiet"]) == 2
    assert "not writable" in capsys.readouterr().err


def test_existing_output_folder_is_not_overwritten(tmp_path, capsys):
    out = tmp_path / "ds"
    out.mkdir()
    (out / "dataset.json").write_text("{}")
    assert main(["run", str(ROOT / "campaigns" / "quick.yaml"), "--out", str(out), "--quiet"]) == 2
    assert "already exists" in capsys.readouterr().err and (out / "dataset.json").read_text() == "{}"


def test_bad_rig_file(tmp_path, capsys):
    rig_file = tmp_path / "rig.yaml"
    rig_file.write_text("axes: {arm_polar: {limits_deg: [10, -10], speed_deg_s: 1, accel_deg_s2: 1}}\n")
    out = tmp_path / "out"
    assert main(["run", str(ROOT / "campaigns" / "quick.yaml"), "--rig", str(rig_file), "--out", str(out)]) == 2
    assert "axes.arm_polar" in capsys.readouterr().err and not out.exists()


def test_missing_campaign_argument(capsys):
    assert main(["run"]) == 2
    assert "give a campaign file" in capsys.readouterr().err
