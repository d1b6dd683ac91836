"""Bad input through the command line: one clear error (exit 2) naming what and where, nothing
moved (the rig is not even started), nothing written or overwritten."""

from pathlib import Path

import pytest
import yaml

from repo_paths import ROOT
from rig.cli.main import main

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


# -- issue 9: everything the validator accepts runs; everything else is exit 2 with nothing written --
@pytest.mark.parametrize("changes, key", [
    (dict(capture={"bracket_stops": 0.3}), "capture.bracket_stops"),       # defect 4: was exit 1 mid-run
    (dict(capture={"roi_px": 12}), "capture.roi_px"),
    (dict(lamp={"warmup_min_s": 1e308}), "lamp.warmup_min_s"),             # was an OverflowError, exit 1
    (dict(incidence=[{"phi": 360, "theta": [30]}]), "incidence[0].phi"),
    (dict(suspenders={"illuminance_drift_limit_rel": 0.0005}), "suspenders.illuminance_drift_limit_rel"),
])
def test_refused_before_anything_is_written(tmp_path, capsys, changes, key):
    f = write(tmp_path, {**GOOD, **changes})
    out = tmp_path / "out"
    assert main(["run", str(f), "--out", str(out), "--quiet"]) == 2
    assert f"'{key}'" in capsys.readouterr().err and not out.exists()
    assert main(["plan", str(f)]) == 2


def test_alias_bomb_and_duplicate_key_through_the_cli(tmp_path, capsys):
    bomb = "a: &a [" + ",".join(['"lol"'] * 9) + "]\n" + "".join(
        f"{c}: &{c} [" + ",".join([f"*{p}"] * 9) + "]\n" for p, c in zip("abcdefgh", "bcdefghi")) + "name: *i\n"
    assert len(bomb) < 400
    assert main(["plan", str(write(tmp_path, text=bomb))]) == 2
    err = capsys.readouterr().err
    assert "refused at line" in err and len(err) < 300
    dup = (ROOT / "campaigns" / "quick.yaml").read_text() + "name: again\n"
    assert main(["plan", str(write(tmp_path, text=dup))]) == 2
    assert "key 'name' given twice" in capsys.readouterr().err


RIG_FILE_CASES = {
    "address without port": "simulated: false\ndevices: {arm: {address: 'modbus-tcp://192.168.10.21'}}\n",
    "infinite speed": "axes: {arm_polar: {limits_deg: [-180, 180], speed_deg_s: .inf, accel_deg_s2: 30}}\n",
    "infinite limits": "axes: {arm_polar: {limits_deg: [-.inf, .inf], speed_deg_s: 15, accel_deg_s2: 30}}\n",
    "camera driver syntax": "simulated: false\ndevices: {camera: {driver: 'python:no colon'}}\n",
}


@pytest.mark.parametrize("name", sorted(RIG_FILE_CASES))
def test_bad_rig_files_are_refused_by_every_command(tmp_path, capsys, name):
    """Before: tracebacks from `rig devices`, a plan from `rig plan`, a failed dataset from `rig run`."""
    rig_file = tmp_path / "rig.yaml"
    rig_file.write_text(RIG_FILE_CASES[name])
    out = tmp_path / "out"
    assert main(["run", str(ROOT / "campaigns" / "quick.yaml"), "--rig", str(rig_file), "--out", str(out),
                 "--quiet"]) == 2
    assert not out.exists()
    assert main(["plan", str(ROOT / "campaigns" / "quick.yaml"), "--rig", str(rig_file)]) == 2
    assert main(["devices", str(rig_file)]) == 2
    err = capsys.readouterr().err
    assert err.count("rig: error: ") == 3 and "Traceback" not in err


def test_camera_plugin_with_the_wrong_signature_is_bad_input(tmp_path, capsys, monkeypatch):
    """Checked before connecting: `rig devices` and `rig run` say what is wrong with exit 2."""
    (tmp_path / "badcam.py").write_text("class Cam:\n    def __init__(self):\n        pass\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    lab = yaml.safe_load((ROOT / "campaigns" / "rigs" / "example-lab.yaml").read_text())
    for name, address in {"arm": "modbus-tcp://127.0.0.1:9", "stage": "modbus-tcp://127.0.0.1:9",
                          "lamp": "socket://127.0.0.1:9", "meter": "/dev/nonexistent-meter"}.items():
        lab["devices"][name]["address"] = address       # never reached: nothing may connect
    lab["devices"]["camera"]["driver"] = "python:badcam:Cam"
    rig_file = tmp_path / "rig.yaml"
    rig_file.write_text(yaml.safe_dump(lab))
    assert main(["devices", str(rig_file)]) == 2
    assert "'devices.camera.driver'" in capsys.readouterr().err
    out = tmp_path / "out"
    assert main(["run", str(ROOT / "campaigns" / "quick.yaml"), "--rig", str(rig_file), "--out", str(out)]) == 2
    assert "not a class implementing" in capsys.readouterr().err and not out.exists()


# -- output folders, plots, imports, pipes (issue 9, dataset/CLI items) --------------------------

@pytest.mark.parametrize("target", ["file", "/dev/null"])
def test_output_that_is_not_a_folder_is_refused(tmp_path, capsys, target):
    out = tmp_path / "file" if target == "file" else Path(target)
    if target == "file":
        out.write_text("keep me")
    assert main(["run", str(ROOT / "campaigns" / "quick.yaml"), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err == (f"rig: error: output {out} exists and is not a folder; choose another --out "
                   "(nothing was overwritten)\n")
    assert target != "file" or out.read_text() == "keep me"


def _imported(tmp_path: Path) -> Path:
    """A small dataset folder (an ALTA import: fast, no rig)."""
    import numpy as np

    from rig.data.alta import write_alta
    src = write_alta(tmp_path / "s.alta", np.radians([[40.0, 0, 30, 180], [40.0, 0, 10, 90]]), [0.5, 0.2],
                     param_in="SPHERICAL_TL_PL_TV_PV", param_out="INV_STERADIAN", ci=[0.01, 0.01])
    assert main(["import", str(src), "--out", str(tmp_path / "ds")]) == 0
    return tmp_path / "ds"


def test_plot_refuses_a_non_empty_output_folder(tmp_path, capsys):
    ds = _imported(tmp_path)
    out = tmp_path / "figures"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    assert main(["plot", str(ds), "--out", str(out)]) == 2
    assert "already exists and is not empty; choose another --out" in capsys.readouterr().err
    assert [p.name for p in out.iterdir()] == ["notes.txt"]


@pytest.mark.parametrize("row, ci, words", [
    ("0.7 0 0.5 3.14 -0.2", "", "BRDF value -0.2 is negative"),
    ("0.7 0 0.5 3.14 0.2", " -0.01", "uncertainty ±-0.01 is negative"),
    ("0.7 0 0.5 3.14 1e308", "", None),         # fine: a huge BRDF is still a number
])
def test_import_refuses_negative_brdf_and_uncertainty(tmp_path, capsys, row, ci, words):
    src = tmp_path / "s.alta"
    src.write_text(f"#DIM 4 1\n#PARAM_IN SPHERICAL_TL_PL_TV_PV\n#PARAM_OUT INV_STERADIAN\n#VS {1 if ci else 0}\n"
                   f"0.5 0 0.3 3.14 0.4{' 0.01' if ci else ''}\n{row}{ci}\n")
    out = tmp_path / "ds"
    code = main(["import", str(src), "--out", str(out)])
    if words is None:
        assert code == 0
        return
    assert code == 2 and f"{src}:6: {words}" in capsys.readouterr().err and not out.exists()


def test_a_closed_output_pipe_is_not_a_traceback():
    import subprocess
    import sys

    proc = subprocess.Popen([sys.executable, "-m", "rig.cli.main", "plan", str(ROOT / "campaigns" / "quick.yaml")],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    proc.stdout.close()                               # `rig plan … | head` once head has its lines
    code = proc.wait(timeout=60)
    err = proc.stderr.read().decode()
    assert code == 141 and err == "", err             # 128 + SIGPIPE, as a shell reports it; no traceback


# -- issue 30: a rig that cannot be reached leaves no dataset folder --------------------------------------------

def _closed_port() -> int:
    """A loopback port nothing listens on."""
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_a_rig_that_cannot_be_reached_leaves_no_dataset_folder(tmp_path, capsys):
    """Before: a `failed` dataset folder with no point, which the rerun of the same command then refused."""
    port = _closed_port()
    rig = {"name": "unreachable", "simulated": False, "lamp": {"voltage_limit_v": 14.0},
           "devices": {name: {"address": f"modbus-tcp://127.0.0.1:{port}"} for name in ("arm", "stage")}
           | {"lamp": {"address": f"socket://127.0.0.1:{port}"}, "meter": {"address": f"socket://127.0.0.1:{port}"},
              "camera": {"driver": "rig-sim-camera", "address": f"socket://127.0.0.1:{port}"}}}
    rig_file = tmp_path / "rig.yaml"
    rig_file.write_text(yaml.safe_dump(rig))
    out = tmp_path / "runs" / "ds"
    assert main(["run", str(ROOT / "campaigns" / "quick.yaml"), "--rig", str(rig_file), "--out", str(out),
                 "--quiet"]) == 1
    err = capsys.readouterr().err
    assert "rig: campaign failed before any point: camera: " in err and "nothing was written" in err, err
    assert not (tmp_path / "runs").exists()
