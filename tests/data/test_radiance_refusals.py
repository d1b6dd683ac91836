"""The Radiance exports refuse what they cannot make, with one message and exit 2: no measured point (`radiance`
exited 0 with an empty folder), one incidence only (`radiance-xml` from the data printed pabopto2bsdf's raw
usage text). Nothing is left behind."""

from pathlib import Path

import pytest

from rig.cli.main import main


@pytest.fixture(scope="module")
def tape_lines(cea_dir) -> tuple[list[str], list[str]]:
    lines = (cea_dir / "retro-gray-tape.alta").read_text().splitlines()
    return [x for x in lines if x.startswith("#")], [x for x in lines if x and not x.startswith("#")]


def _import(folder: Path, head: list[str], rows: list[str]) -> Path:
    (folder / "t.alta").write_text("\n".join(head + rows) + "\n")
    assert main(["import", str(folder / "t.alta"), "--out", str(folder / "ds")]) == 0
    return folder / "ds"


def _refused(argv: list[str], capsys, said: str) -> None:
    capsys.readouterr()                          # what the import said
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.startswith("rig: error: ") and err.count("\n") == 1 and said in err, err


def test_one_incidence_is_refused_before_pabopto2bsdf_runs(tmp_path, capsys, tape_lines):
    head, data = tape_lines
    theta_15 = [row for row in data if row.split()[0].startswith("0.2617")][::20]     # θ_light = 15° only
    ds = _import(tmp_path, head, theta_15)
    out = tmp_path / "x.xml"
    _refused(["export", str(ds), "--format", "radiance-xml", "--out", str(out)], capsys,
             "one incidence only; pabopto2bsdf interpolates between incidences and needs at least two")
    assert not out.exists() and [p.name for p in tmp_path.iterdir()] == ["t.alta", "ds"]


@pytest.mark.parametrize("fmt", ["radiance", "radiance-xml"])
def test_no_measured_point_is_refused(tmp_path, capsys, tape_lines, fmt):
    head, data = tape_lines
    ds = _import(tmp_path, head, data[:3])
    brdf = ds / "brdf.csv"
    brdf.write_text(brdf.read_text().splitlines()[0] + "\n")           # the header only: no point
    out = tmp_path / "out"
    _refused(["export", str(ds), "--format", fmt, "--out", str(out)], capsys, "no measured point to export")
    assert not out.exists()
