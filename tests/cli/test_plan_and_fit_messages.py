"""Messages of `rig plan`, `rig fit`, `rig predict` and the road export that said something else than what is so
(issue 30, smaller items): an incidence of 84.99° printed as 85.0°; an empty dataset reported as "no row without
the flags …" (or "no incidence has three … views"); the dataset's folder named twice; a `--json` written over an
existing file."""

import json
from pathlib import Path

import pytest

from repo_paths import ROOT
from rig.cli.main import main


def test_plan_prints_a_planned_angle_as_given(tmp_path, capsys):
    campaign = (ROOT / "campaigns" / "quick.yaml").read_text().replace("theta: [0, 30, 60, 80, 85]",
                                                                       "theta: [0, 30, 84.99]")
    (tmp_path / "c.yaml").write_text(campaign)
    assert main(["plan", str(tmp_path / "c.yaml")]) == 0
    series = [line for line in capsys.readouterr().out.splitlines() if "°, " in line and " / " in line]
    assert [line.split(")")[0].split("(")[1] for line in series] == ["  0.0°,   0.0°", " 30.0°,   0.0°",
                                                                     "84.99°,   0.0°"]


@pytest.fixture
def imported(cea_dir, tmp_path) -> Path:
    lines = (cea_dir / "retro-gray-tape.alta").read_text().splitlines()
    head, data = [x for x in lines if x.startswith("#")], [x for x in lines if x and not x.startswith("#")]
    (tmp_path / "t.alta").write_text("\n".join(head + data[::300]) + "\n")
    assert main(["import", str(tmp_path / "t.alta"), "--out", str(tmp_path / "ds")]) == 0
    return tmp_path / "ds"


def _error(argv: list[str], capsys) -> str:
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("rig: error: ") and err.count("\n") == 1, err
    return err


def test_fit_of_an_empty_dataset_says_so_naming_the_folder_once(imported, capsys):
    brdf = imported / "brdf.csv"
    brdf.write_text(brdf.read_text().splitlines()[0] + "\n")
    err = _error(["fit", str(imported), "--model", "lambert"], capsys)
    assert "no measured point to fit" in err and "flags" not in err
    assert err.count(str(imported)) == 1


def test_fit_with_every_point_excluded_names_the_folder_once(imported, capsys):
    err = _error(["fit", str(imported), "--model", "lambert", "--exclude-flag", "imported"], capsys)
    assert "no point left to fit" in err and err.count(str(imported)) == 1


def test_fit_json_never_overwrites(imported, tmp_path, capsys):
    existing = tmp_path / "fit.json"
    existing.write_text('{"kept": true}')
    err = _error(["fit", str(imported), "--model", "lambert", "--json", str(existing)], capsys)
    assert "already exists" in err and json.loads(existing.read_text()) == {"kept": True}


@pytest.mark.parametrize("command", [
    ["predict", "--at", "AT", "--out", "OUT"],
    ["predict", "--at", "AT", "--method", "model", "--model", "lambert", "--out", "OUT"],
    ["export", "--format", "road", "--model", "lambert", "--out", "OUT"]])
def test_predict_and_road_of_an_empty_dataset_say_so(imported, tmp_path, capsys, command):
    brdf = imported / "brdf.csv"
    brdf.write_text(brdf.read_text().splitlines()[0] + "\n")
    (tmp_path / "at.csv").write_text("theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg\n30,0,30,180\n")
    files = {"AT": str(tmp_path / "at.csv"), "OUT": str(tmp_path / "out")}
    err = _error([command[0], str(imported), *(files.get(a, a) for a in command[1:])], capsys)
    assert "no measured point to predict from" in err and err.count(str(imported)) == 1
    assert not (tmp_path / "out").exists()
