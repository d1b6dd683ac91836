"""Everything that reads a dataset folder or an ALTA file, fed what users and crashes leave behind
(issue 9): a torn last line, a manifest that is a list, a corrupt line in events.jsonl, a missing
brdf.csv, a campaign recorded by a relative path; then random mutations (hypothesis) of a real
small dataset and of a small ALTA file.

Every command must return exit 0 or 2 (1 only for a device failure, which none of these are),
never raise, write nothing on exit 2, and never change the folder it reads (a resume may cut a
torn last line, which is what it is for).
"""

import json
import shutil
import tempfile
from collections import namedtuple
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rig.acquisition import diskspace
from rig.cli.main import main
from rig.data.alta import write_alta
from rig.data.dataset_format import DatasetError
from rig.data.dataset_reader import load
from rig.data.folderlock import LOCK_NAME

TINY = {
    "name": "tiny",
    "sample": {"id": "S", "simulated_brdf": {"model": "lambert", "params": {"kd": 0.5}}},
    "incidence": [{"phi": 0, "theta": [0, 40]}],
    "viewing": [{"centred_on": "normal", "theta": [10, 30], "phi": [0, 90, 180, 270]}],
    "lamp": {"warmup_min_s": 60},
}
LOGS = ("brdf.csv", "events.jsonl")
Usage = namedtuple("Usage", "total used free")


@pytest.fixture(scope="module")
def base(tmp_path_factory) -> dict[str, Path]:
    """A complete dataset of a tiny simulated campaign, and an interrupted copy missing 6 rows."""
    root = tmp_path_factory.mktemp("readers")
    campaign = root / "tiny.yaml"
    campaign.write_text(yaml.safe_dump(TINY))
    complete = root / "complete"
    assert main(["run", str(campaign), "--out", str(complete), "--quiet"]) == 0
    interrupted = root / "interrupted"
    shutil.copytree(complete, interrupted)
    lines = (interrupted / "brdf.csv").read_text().splitlines(keepends=True)
    (interrupted / "brdf.csv").write_text("".join(lines[:-6]))
    manifest = json.loads((interrupted / "dataset.json").read_text())
    (interrupted / "dataset.json").write_text(json.dumps({**manifest, "status": "interrupted"}))
    return {"campaign": campaign, "complete": complete, "interrupted": interrupted}


def snapshot(folder: Path) -> dict[str, bytes]:
    """Every file's bytes, the lock file left out (a writer creates it; it holds no data)."""
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*"))
            if p.is_file() and p.name != LOCK_NAME}


def unchanged_but_torn_tails_cut(before: dict[str, bytes], after: dict[str, bytes]) -> bool:
    """`after` equals `before`, except that a log may have lost a last line without a newline."""
    if before.keys() != after.keys():
        return False
    for name, old in before.items():
        new = after[name]
        if new != old and not (name in LOGS and old.startswith(new) and b"\n" not in old[len(new):]
                               and (new == b"" or new.endswith(b"\n"))):
            return False
    return True


def copy(src: Path, where: Path) -> Path:
    dst = where / "ds"
    shutil.copytree(src, dst)
    return dst


# -- the cases of issue 9 ----------------------------------------------------------------------

@pytest.mark.parametrize("command", ["fit", "export", "plot"])
def test_readers_ignore_a_torn_last_line_with_a_warning(base, tmp_path, capsys, command):
    ds = copy(base["complete"], tmp_path)
    with open(ds / "brdf.csv", "a") as fh:                # exactly what a kill -9 mid-write leaves
        fh.write("01-007,1,40.0,0.0,3")
    before = snapshot(ds)
    out = tmp_path / "out"
    argv = {"fit": ["fit", str(ds), "--model", "lambert"],
            "export": ["export", str(ds), "--format", "csv", "--out", str(out)],
            "plot": ["plot", str(ds), "--out", str(out)]}[command]
    assert main(argv) == 0
    err = capsys.readouterr().err
    assert f"rig: warning: {ds / 'brdf.csv'}: ignored a torn last line (19 bytes" in err
    assert snapshot(ds) == before                         # a reader never changes the folder
    assert len(load(ds)) == 16


def test_load_names_the_line_of_a_malformed_row(base, tmp_path):
    ds = copy(base["complete"], tmp_path)
    lines = (ds / "brdf.csv").read_text().splitlines(keepends=True)
    lines[3] = lines[3].replace(",", ",x", 1)
    (ds / "brdf.csv").write_text("".join(lines))
    with pytest.raises(DatasetError, match=r"brdf.csv:4: column series: 'x\d' is not a finite number"):
        load(ds)


@pytest.mark.parametrize("damage, expected", [
    ("manifest_list", "dataset.json: a JSON array, not the manifest's object"),
    ("events_garbage", "events.jsonl:3: not valid JSON"),
    ("events_bad_row", "events.jsonl:{pending}: a point_pending record whose row's brdf_per_sr is 'x'"),
    ("brdf_missing", "brdf.csv: missing"),
    ("rig_config", "rig.config is not a valid rig configuration"),
])
def test_resume_of_a_damaged_folder_is_refused_and_changes_nothing(base, tmp_path, capsys, damage, expected):
    ds = copy(base["interrupted"], tmp_path)
    events = (ds / "events.jsonl").read_text().splitlines(keepends=True)
    pending = next(k for k, e in enumerate(events) if '"point_pending"' in e)
    if damage == "manifest_list":
        (ds / "dataset.json").write_text("[1, 2]\n")
    elif damage == "events_garbage":
        events[2] = '{"time_utc": "2026-01-01", "ev\x00ent": \n'
        (ds / "events.jsonl").write_text("".join(events))
    elif damage == "events_bad_row":
        record = json.loads(events[pending])
        record["row"]["brdf_per_sr"] = "x"
        events[pending] = json.dumps(record) + "\n"
        (ds / "events.jsonl").write_text("".join(events))
    elif damage == "brdf_missing":
        (ds / "brdf.csv").unlink()
    else:
        manifest = json.loads((ds / "dataset.json").read_text())
        manifest["rig"]["config"] = {"axes": "none"}
        (ds / "dataset.json").write_text(json.dumps(manifest))
    before = snapshot(ds)
    assert main(["run", "--resume", str(ds), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("rig: error: ") and err.count("\n") == 1
    assert expected.format(pending=pending + 1) in err
    assert snapshot(ds) == before


def test_resume_is_refused_when_the_rest_does_not_fit(base, tmp_path, monkeypatch, capsys):
    ds = copy(base["interrupted"], tmp_path)
    before = snapshot(ds)
    monkeypatch.setattr(diskspace.shutil, "disk_usage", lambda path: Usage(10**9, 10**9 - 50_000, 50_000))
    assert main(["run", "--resume", str(ds), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"{ds}: not enough free disk space" in err and "50.0 kB free" in err and "move the folder" in err
    assert snapshot(ds) == before


def test_new_manifests_record_the_campaign_by_absolute_path(base):
    recorded = json.loads((base["complete"] / "dataset.json").read_text())["campaign"]["file"]
    assert Path(recorded).is_absolute() and Path(recorded) == base["campaign"]


def test_resume_from_another_folder_finds_an_old_relative_campaign_path(base, tmp_path, monkeypatch):
    project = tmp_path / "project"
    (project / "runs").mkdir(parents=True)
    shutil.copy(base["campaign"], project / "tiny.yaml")
    ds = copy(base["interrupted"], project / "runs")
    manifest = json.loads((ds / "dataset.json").read_text())
    manifest["campaign"]["file"] = "tiny.yaml"        # what older versions wrote: relative to the run's cwd
    (ds / "dataset.json").write_text(json.dumps(manifest))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(["run", "--resume", str(ds), "--quiet"]) == 0
    assert json.loads((ds / "dataset.json").read_text())["status"] == "complete" and len(load(ds)) == 16


# -- random mutations --------------------------------------------------------------------------

GARBAGE = st.sampled_from([b"", b"\x00\xff\xfe", b"nan", b"-1e309", b"1e308", b"{", b"[]", b'"x"', b",,,,",
                           b"\n", b"\xe2\x82", b"inf", b"null", b"-0.5", b'{"event": "point_pending", "row": {}}',
                           b'{"event": "points_discarded", "point_ids": 3}']) | st.binary(max_size=30)
WRONG_JSON = [[], "x", 3, None, {"format": 3}, {"format": "rig-brdf-dataset"}]
MANIFEST_KEYS = ["campaign", "rig", "status", "resumes", "sample", "format"]


@st.composite
def mutation(draw, files):
    return (draw(st.sampled_from(files)),
            draw(st.sampled_from(["truncate", "insert", "delete", "replace_line", "torn", "duplicate_line",
                                  "wrong_json"])),
            draw(st.floats(0, 1)), draw(GARBAGE), draw(st.integers(0, 100)))


def mutate(folder: Path, name: str, op: str, where: float, garbage: bytes, pick: int) -> None:
    path = folder / name
    if not path.exists():
        return
    data = path.read_bytes()
    cut = int(where * len(data))
    lines = data.split(b"\n")
    k = min(int(where * len(lines)), len(lines) - 1)
    if op == "delete":
        path.unlink()
        return
    if op == "truncate":
        data = data[:cut]
    elif op == "insert":
        data = data[:cut] + garbage + data[cut:]
    elif op == "replace_line":
        data = b"\n".join(lines[:k] + [garbage] + lines[k + 1:])
    elif op == "torn":
        data = data + (garbage.replace(b"\n", b"") or b"00-0")
    elif op == "duplicate_line":
        data = b"\n".join(lines[:k + 1] + lines[k:])
    elif name == "dataset.json":                          # wrong_json: a valid JSON of the wrong shape
        try:
            manifest = json.loads(data)
        except ValueError:                                # already garbled by an earlier mutation
            manifest = None
        if pick % 2 or not isinstance(manifest, dict):
            data = json.dumps(WRONG_JSON[pick % len(WRONG_JSON)]).encode()
        else:
            manifest[MANIFEST_KEYS[pick % len(MANIFEST_KEYS)]] = WRONG_JSON[pick % len(WRONG_JSON)]
            data = json.dumps(manifest).encode()
    else:                                                 # wrong_json elsewhere: a cell or a line of the wrong type
        text = data.decode("utf-8", "replace").split("\n")
        row = k if k < len(text) - 1 else 0
        cells = text[row].split(",")
        cells[pick % len(cells)] = json.dumps(WRONG_JSON[pick % len(WRONG_JSON)])
        text[row] = ",".join(cells)
        data = "\n".join(text).encode()
    path.write_bytes(data)


def check_reader(argv: list[str], ds: Path, out: Path) -> None:
    before = snapshot(ds)
    code = main(argv)
    assert isinstance(code, int) and code in (0, 2), argv
    if code == 2:
        assert not out.exists(), f"{argv}: exit 2 but {out} was written"
    assert snapshot(ds) == before, f"{argv} changed the folder it reads"


FOLDER_FILES = ["dataset.json", "brdf.csv", "skipped.csv"]


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(changes=st.lists(mutation(FOLDER_FILES), min_size=1, max_size=3), command=st.sampled_from(["fit", "export"]))
def test_fuzz_fit_and_export_of_mutated_folders(base, changes, command):
    with tempfile.TemporaryDirectory() as tmp:
        ds = copy(base["complete"], Path(tmp))
        for change in changes:
            mutate(ds, *change)
        out = Path(tmp) / "out"
        argv = (["fit", str(ds), "--model", "lambert", "--json", str(out)] if command == "fit"
                else ["export", str(ds), "--format", "csv", "--out", str(out)])
        check_reader(argv, ds, out)


@settings(max_examples=5, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(changes=st.lists(mutation(FOLDER_FILES), min_size=1, max_size=2))
def test_fuzz_plot_of_mutated_folders(base, changes):
    with tempfile.TemporaryDirectory() as tmp:
        ds = copy(base["complete"], Path(tmp))
        for change in changes:
            mutate(ds, *change)
        out = Path(tmp) / "plots"
        check_reader(["plot", str(ds), "--out", str(out)], ds, out)


@settings(max_examples=12, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(changes=st.lists(mutation(["dataset.json", "brdf.csv", "events.jsonl"]), min_size=1, max_size=2))
def test_fuzz_resume_of_mutated_folders(base, changes):
    with tempfile.TemporaryDirectory() as tmp:
        ds = copy(base["interrupted"], Path(tmp))
        for change in changes:
            mutate(ds, *change)
        before = snapshot(ds)
        code = main(["run", "--resume", str(ds), "--quiet"])
        assert isinstance(code, int) and code in (0, 2)
        if code == 2:
            assert unchanged_but_torn_tails_cut(before, snapshot(ds))
        else:
            assert json.loads((ds / "dataset.json").read_text())["status"] == "complete"


VALID_ALTA_ROWS = np.radians([[40.0, 0.0, 30.0, 180.0], [40.0, 0.0, 10.0, 90.0], [20.0, 90.0, 5.0, 0.0]])


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(op=st.sampled_from(["truncate", "insert", "replace_line", "torn", "duplicate_line", "cell"]),
       where=st.floats(0, 1), garbage=GARBAGE,
       cell=st.sampled_from(["nan", "-inf", "-0.3", "1e308", "-1e-300", "1e400", "0x10", "1_0", "", "5 6"]),
       vs=st.sampled_from([0, 1, 2]))
def test_fuzz_import_of_mutated_alta_files(op, where, garbage, cell, vs):
    with tempfile.TemporaryDirectory() as tmp:
        ci = {0: None, 1: [0.01, 0.02, 0.03], 2: [[0.4, 0.6], [0.1, 0.3], [0.2, 0.2]]}[vs]
        src = write_alta(Path(tmp) / "s.alta", VALID_ALTA_ROWS, [0.5, 0.2, 0.25], param_in="SPHERICAL_TL_PL_TV_PV",
                         param_out="INV_STERADIAN", ci=ci, header={"SAMPLE": '"S"'})
        if op == "cell":
            lines = src.read_text().split("\n")
            row = len(lines) - 2 - int(where * 2.99)           # one of the three data rows
            cells = lines[row].split(" ")
            cells[int(where * 100) % len(cells)] = cell
            lines[row] = " ".join(cells)
            src.write_text("\n".join(lines))
        else:
            mutate(Path(tmp), "s.alta", op, where, garbage, 0)
        out = Path(tmp) / "imported"
        code = main(["import", str(src), "--out", str(out)])
        assert isinstance(code, int) and code in (0, 2)
        if code == 2:
            assert not out.exists()
        else:
            ds = load(out)
            assert np.all(ds["brdf_per_sr"] >= 0) and not np.any(ds["u_brdf_per_sr"] < 0)   # NaN: no #VS
