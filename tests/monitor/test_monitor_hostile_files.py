"""rig.monitor.folder on folders whose files hold what rig never writes (issue 30, item 10 and the folder replaced
by a copy): each bad line is skipped, counted and named, the rest of its batch is kept and the state stays valid
JSON; a FIFO in the place of a file hangs nothing; a folder replaced by another run's files in the same inodes
starts over instead of mixing the two runs."""

from __future__ import annotations

import json
import os
import threading
from typing import Any

import pytest
from shared import Folder, row, utc, warm

from rig.data.dataset_format import BRDF_COLUMNS, csv_line
from rig.monitor.files import MAX_DEPTH, MAX_LINE_BYTES

#: Wall seconds a read of the folder may take before the test calls it hung (a guard, never a measurement).
HANG_GUARD_S = 10.0


def strict(snapshot: dict[str, Any]) -> dict[str, Any]:
    """The snapshot as the server sends it: JSON without NaN or Infinity (json.dumps raises on them)."""
    return json.loads(json.dumps(snapshot, allow_nan=False))


BAD_EVENTS = {
    "NaN time": '{"time_utc": NaN, "event": "warning", "rig_time_s": 102.0}',
    "Infinity time": '{"time_utc": -Infinity, "event": "warning"}',
    "float beyond a double": '{"time_utc": "2026-01-01T00:00:10Z", "event": "warning", "rig_time_s": 1e999}',
    "integer of 5000 digits": '{"event": "illuminance", "rig_time_s": ' + "7" * 5000 + "}",
    "list as the pending id": '{"event": "point_pending", "row": {"point_id": ["01-009"], "series": 1}}',
    "list as a discarded id": '{"event": "points_discarded", "point_ids": ["01-000", ["x"]]}',
    "nested beyond the recursion limit": '{"event": "warning", "x": ' + "[" * 100_000 + "]" * 100_000 + "}",
    "nested beyond MAX_DEPTH": '{"event": "warning", "x": ' + "[" * 900 + "]" * 900 + "}",
    "not an object": "[1, 2]",
}


@pytest.mark.parametrize("line", BAD_EVENTS.values(), ids=BAD_EVENTS.keys())
def test_a_bad_event_line_is_skipped_and_named_and_the_rest_of_its_batch_is_kept(tmp_path, line):
    f = Folder(tmp_path / "run")
    warm(f)
    f.pending("01-000", 110.0)
    f.append("events.jsonl", line + "\n")
    f.pending("01-001", 120.0)                              # in the same batch, after the bad line
    f.event("suspended", 121.0, device="lamp", reason="lamp current 0.000 A")
    s = strict(f.look())
    assert s["progress"]["done"] == 2 and s["phase"] == "paused"
    assert s["bad_lines"] == 1
    assert len(s["warnings"]) == 1 and s["warnings"][0].startswith("events.jsonl line 6: ")
    assert {c["id"] for c in s["changes"] if c["k"] == "p"} == {"01-000", "01-001"}
    f.pending("01-002", 130.0)                              # and the next looks go on
    s = strict(f.look(s["next"]))
    assert [c["id"] for c in s["changes"] if c["k"] == "p"] == ["01-002"] and s["bad_lines"] == 1


def test_the_reasons_say_what_was_wrong(tmp_path):
    f = Folder(tmp_path / "run")
    for name in ("NaN time", "integer of 5000 digits", "list as the pending id", "nested beyond MAX_DEPTH"):
        f.append("events.jsonl", BAD_EVENTS[name] + "\n")
    warnings = strict(f.look())["warnings"]
    assert "NaN is not a JSON number" in warnings[0]
    assert "digits" in warnings[1]
    assert "point_id is not text" in warnings[2]
    assert f"deeper than {MAX_DEPTH}" in warnings[3]


def test_a_csv_row_with_a_128_kb_field_is_skipped_and_the_next_rows_kept(tmp_path):
    f = Folder(tmp_path / "run")
    warm(f)
    f.row("01-000", 110.0)
    huge = row("01-001", 111.0)
    huge["flags"] = "x" * (128 * 1024 + 1)                   # beyond csv's field_size_limit
    f.append("brdf.csv", csv_line(huge[c] for c in BRDF_COLUMNS))
    f.row("01-002", 112.0)
    s = strict(f.look())
    assert s["progress"]["in_csv"] == 2 and s["bad_lines"] == 1
    assert s["warnings"][0].startswith("brdf.csv line 3: not a CSV row")


def test_a_line_longer_than_the_limit_is_skipped_once_even_while_it_is_written(tmp_path):
    f = Folder(tmp_path / "run")
    warm(f)
    f.look()
    f.append("events.jsonl", "{" + " " * MAX_LINE_BYTES)     # no end yet
    s = strict(f.look())
    assert s["bad_lines"] == 1 and f"longer than {MAX_LINE_BYTES} bytes" in s["warnings"][0]
    f.append("events.jsonl", " " * 1000 + "}\n")            # its end
    f.pending("01-000", 110.0)
    s = strict(f.look())
    assert s["bad_lines"] == 1 and s["progress"]["done"] == 1


def test_absurd_manifest_and_times_give_no_nan_or_infinity(tmp_path):
    f = Folder(tmp_path / "run", counts={"planned": 10 ** 4000, "skipped": -(10 ** 4000)}, sample={"id": [1, 2]})
    warm(f)
    for pid, rig_s in (("01-000", -1e308), ("01-001", 1e308)):
        f.append("events.jsonl", json.dumps({"time_utc": utc(200.0), "event": "point_pending", "rig_time_s": rig_s,
                                             "row": {**row(pid, 200.0), "rig_time_s": rig_s}}) + "\n")
    s = strict(f.look())
    assert s["sample"] is None and s["progress"]["done"] == 2
    assert all(v is None or abs(v) < 1e309 for v in s["eta"].values())


def look_guarded(f: Folder) -> dict[str, Any]:
    """f.look() in a thread, failing the test (not hanging it) if the read never returns."""
    result: dict[str, Any] = {}
    reader = threading.Thread(target=lambda: result.update(f.look()), daemon=True)
    reader.start()
    reader.join(HANG_GUARD_S)
    return result


@pytest.mark.parametrize("name", ["events.jsonl", "brdf.csv", "skipped.csv", "dataset.json", ".lock"])
def test_a_fifo_in_the_place_of_a_file_hangs_nothing_and_is_named(tmp_path, name):
    f = Folder(tmp_path / "run")
    warm(f)
    f.look()
    fifo = f.path / name
    fifo.unlink()
    os.mkfifo(fifo)
    try:
        s = look_guarded(f)
    finally:                     # a reader blocked in open() (the code before the fix) is released
        try:
            os.close(os.open(fifo, os.O_WRONLY | os.O_NONBLOCK))
        except OSError:
            pass
    assert s, f"reading the folder hung on {name} as a FIFO"
    strict(s)
    if name == "dataset.json":
        assert s["phase"] == "unreadable" and "a FIFO" in s["detail"]
    elif name != ".lock":
        assert any(w.startswith(f"{name}: a FIFO") for w in s["warnings"]), s["warnings"]


def rewrite_in_place(path, text: str) -> None:
    """Replace a file's content keeping its inode: what a copy reusing the freed inode numbers looks like."""
    with open(path, "r+", encoding="utf-8") as fh:
        fh.truncate(0)
        fh.write(text)


def test_a_folder_replaced_by_a_copy_in_the_same_inodes_starts_over_without_mixing(tmp_path):
    a = Folder(tmp_path / "a")
    warm(a)
    a.pending("01-000", 110.0)
    a.row("01-000", 110.0)
    b = Folder(tmp_path / "b", created_utc=utc(5000.0))      # another run, longer than what was read of a
    warm(b)
    for i in range(1, 6):
        b.pending(f"02-{i:03d}", 200.0 + i)
        b.row(f"02-{i:03d}", 200.0 + i)
    first = a.look()
    for name in ("events.jsonl", "brdf.csv", "dataset.json"):
        assert name == "dataset.json" or (b.path / name).stat().st_size > (a.path / name).stat().st_size
        rewrite_in_place(a.path / name, (b.path / name).read_text())
    s = a.look(first["next"])
    assert s["generation"] != first["generation"]
    assert {c["id"] for c in s["changes"] if c["k"] == "p"} == {f"02-{i:03d}" for i in range(1, 6)}
    assert s["progress"]["done"] == 5 and s["created_utc"] == utc(5000.0) and s["bad_lines"] == 0


def test_an_events_file_rewritten_in_place_with_other_first_lines_starts_over(tmp_path):
    f = Folder(tmp_path / "run")
    warm(f)
    first = f.look()
    text = (f.path / "events.jsonl").read_text()
    rewrite_in_place(f.path / "events.jsonl", text.replace(utc(0.0), utc(1.0), 1) + text)
    again = f.look(first["next"])
    assert again["generation"] != first["generation"] and again["bad_lines"] == 0
