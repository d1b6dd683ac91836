"""Every JSON a command reads (dataset.json, events.jsonl, a fit, road.json) with hostile content: numbers of more
digits than Python converts, nesting deeper than its recursion limit, bytes that are not UTF-8, wrong types.
Each command exits 2 with one line naming the file (and the line where it is known), never a traceback
(issue 30, item 12)."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from rig.acquisition.resume import ResumeError, _pending_rows
from rig.cli.main import main
from rig.core.jsonfile import JsonFileError, parse_json

HUGE = "1" * 5000
DEEP = "[" * 200_000 + "]" * 200_000


@pytest.fixture(scope="module")
def base(cea_dir, tmp_path_factory) -> Path:
    """A small imported dataset (every 200th point of the gray tape), a valid fit, a directions file."""
    folder = tmp_path_factory.mktemp("hostile")
    lines = (cea_dir / "retro-gray-tape.alta").read_text().splitlines()
    head, data = [x for x in lines if x.startswith("#")], [x for x in lines if x and not x.startswith("#")]
    (folder / "tape.alta").write_text("\n".join(head + data[::200]) + "\n")
    assert main(["import", str(folder / "tape.alta"), "--out", str(folder / "ds")]) == 0
    (folder / "fit.json").write_text(json.dumps({"model": "lambert", "params": {"kd": 0.05}}))
    (folder / "at.csv").write_text("theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg\n30,0,30,180\n")
    return folder


@pytest.fixture
def work(base, tmp_path) -> Path:
    shutil.copytree(base, tmp_path / "w")
    return tmp_path / "w"


def _manifest_with(ds: Path, line_2: bytes) -> None:
    """dataset.json with `line_2` inserted after its first line ("{")."""
    lines = (ds / "dataset.json").read_bytes().split(b"\n")
    lines.insert(1, line_2)
    (ds / "dataset.json").write_bytes(b"\n".join(lines))


def _manifest_set(ds: Path, key: str, value: object) -> None:
    manifest = json.loads((ds / "dataset.json").read_text())
    (ds / "dataset.json").write_text(json.dumps({**manifest, key: value}))


#: Hostile dataset.json contents: how to make it, and what the message must say.
MANIFESTS = {
    "huge integer": (lambda ds: _manifest_with(ds, f'  "x": {HUGE},'.encode()), ":2: a number of more than 4300"),
    "deep nesting": (lambda ds: (ds / "dataset.json").write_text(DEEP), "nested too deeply"),
    "not UTF-8": (lambda ds: _manifest_with(ds, b'  "x": "\xff",'), ":2: not UTF-8 text"),
    "truncated": (lambda ds: (ds / "dataset.json").write_text((ds / "dataset.json").read_text()[:40]),
                  "not valid JSON"),
    "sample is a list": (lambda ds: _manifest_set(ds, "sample", [1]), "'sample' is a JSON array"),
    "lone surrogate": (lambda ds: _manifest_set(ds, "sample", {"id": "\ud800x"}), "lone UTF-16 surrogate"),
}

COMMANDS = {
    "plot": lambda w: ["plot", str(w / "ds"), "--out", str(w / "figs")],
    "report": lambda w: ["report", str(w / "ds"), "--out", str(w / "r.html")],
    "fit": lambda w: ["fit", str(w / "ds"), "--model", "lambert"],
    "export": lambda w: ["export", str(w / "ds"), "--format", "csv", "--out", str(w / "x.csv")],
    "export road": lambda w: ["export", str(w / "ds"), "--format", "road", "--fit", str(w / "fit.json"),
                              "--out", str(w / "road.json")],
    "predict": lambda w: ["predict", str(w / "ds"), "--at", str(w / "at.csv"), "--out", str(w / "p.csv")],
}


def _refused(argv: list[str], capsys, *expected: str) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("rig: error: "), err
    for text in expected:
        assert text in err, err
    return err


@pytest.mark.parametrize("command", COMMANDS)
@pytest.mark.parametrize("hostile", MANIFESTS)
def test_a_hostile_manifest_is_refused_naming_the_file(work, capsys, command, hostile):
    make, said = MANIFESTS[hostile]
    make(work / "ds")
    _refused(COMMANDS[command](work), capsys, str(work / "ds" / "dataset.json"), said)


#: Hostile fit files, and what the message must say.
FITS = {
    "huge integer": (f'{{"model": "lambert",\n "params": {{"kd": {HUGE}}}}}', ":2: a number of more than"),
    "deep nesting": (DEEP, "nested too deeply"),
    "not UTF-8": (b'{"model": "lambert\xff"}', ":1: not UTF-8 text"),
    "params a list": ('{"model": "lambert", "params": [0.1]}', "'params' must give kd"),
    "param a string": ('{"model": "lambert", "params": {"kd": "0.1"}}', "'params' must give kd"),
    "unknown model": ('{"model": 7, "params": {}}', "'model' is '7'"),
    "covariance rows a list": ('{"model": "lambert", "params": {"kd": 0.1}, "covariance": {"kd": [1]}}',
                               "must hold numbers or null"),
    "an array": ("[]", "a JSON array, not a fit's object"),
}

FIT_COMMANDS = {
    "plot": lambda w: ["plot", str(w / "ds"), "--fit", str(w / "bad.json"), "--out", str(w / "figs")],
    "report": lambda w: ["report", str(w / "ds"), "--fit", str(w / "bad.json"), "--out", str(w / "r.html")],
    "export road": lambda w: ["export", str(w / "ds"), "--format", "road", "--fit", str(w / "bad.json"),
                              "--out", str(w / "road.json")],
    "predict": lambda w: ["predict", str(w / "ds"), "--at", str(w / "at.csv"), "--method", "model",
                          "--fit", str(w / "bad.json"), "--out", str(w / "p.csv")],
}


@pytest.mark.parametrize("command", FIT_COMMANDS)
@pytest.mark.parametrize("hostile", FITS)
def test_a_hostile_fit_is_refused_naming_the_file(work, capsys, command, hostile):
    content, said = FITS[hostile]
    bad = work / "bad.json"
    bad.write_bytes(content if isinstance(content, bytes) else content.encode())
    _refused(FIT_COMMANDS[command](work), capsys, str(bad), said)
    assert not any((work / name).exists() for name in ("figs", "r.html", "road.json", "p.csv"))


@pytest.mark.parametrize(("content", "said"), [
    (f'{{"R_L_mcd_m2_lx": {HUGE}}}', ":1: a number of more than"),
    (DEEP, "nested too deeply"),
    ('{"S1": "high"}', "'S1' is a JSON string, not a number or null"),
    ('{"S1": 0.5, "surface_classes": ["R1"]}', "'surface_classes' is a JSON array, not an object"),
])
def test_a_hostile_road_json_is_refused_by_the_report(work, capsys, content, said):
    bad = work / "road.json"
    bad.write_text(content)
    _refused(["report", str(work / "ds"), "--road", str(bad), "--out", str(work / "r.html")], capsys, str(bad), said)


def test_a_hostile_events_line_is_refused_by_the_report_naming_its_line(work, capsys):
    events = work / "ds" / "events.jsonl"
    with events.open("a") as fh:
        fh.write(f'{{"event": "x", "n": {HUGE}}}\n{{"event": "y"}}\n')
    line = events.read_text().count("\n") - 1
    _refused(["report", str(work / "ds"), "--out", str(work / "r.html")], capsys, f"{events}:{line}: a number of")


def test_parse_json_counts_lines_from_first_line():
    with pytest.raises(JsonFileError, match=r"^f:12: not valid JSON"):
        parse_json('{"a":\n\n}', "f", first_line=10)
    with pytest.raises(JsonFileError, match=r"^f:7: JSON nested too deeply"):
        parse_json(DEEP, "f", first_line=7)


def test_resume_refuses_a_manifest_with_a_huge_number(work):
    """`rig run --resume` reads dataset.json first: exit 2 naming its line, no traceback."""
    _manifest_with(work / "ds", f'  "x": {HUGE},'.encode())
    proc = subprocess.run([sys.executable, "-m", "rig.cli.main", "run", "--resume", str(work / "ds")],
                          capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2, proc.stderr
    assert proc.stderr.startswith(f"rig: error: {work / 'ds' / 'dataset.json'}:2: a number of more than")
    assert "Traceback" not in proc.stderr


@pytest.mark.parametrize(("line", "said"), [(f'{{"event": "x", "n": {HUGE}}}', "a number of more than"),
                                            (DEEP, "JSON nested too deeply")])
def test_resume_names_the_hostile_line_of_events(tmp_path, line, said):
    """The write-ahead log resume replays: its hostile line is a ResumeError naming the line."""
    (tmp_path / "events.jsonl").write_text(f'{{"event": "started"}}\n{line}\n')
    with pytest.raises(ResumeError, match=rf"events.jsonl:2: {said}"):
        _pending_rows(tmp_path)


@pytest.mark.parametrize("rig", [{"config": [1]}, {"config": {"camera": [1], "attenuator": {"filters": [1, "x"]}},
                                                   "identities": [1]}])
def test_the_report_shows_a_dash_for_manifest_parts_of_the_wrong_type(work, capsys, rig):
    """Deeper in the manifest, what the report would show is shown as absent, not a traceback."""
    _manifest_set(work / "ds", "rig", rig)
    assert main(["report", str(work / "ds"), "--out", str(work / "r.html")]) == 0, capsys.readouterr().err
