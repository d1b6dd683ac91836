"""Fuzzing campaign and rig files through the command line, as a user would mistype them (issue 9).

Valid files are mutated (keys deleted, values replaced by wrong types, huge, negative, infinite or
NaN numbers, long strings, nested garbage; unknown keys, duplicate keys, alias bombs) and run
through `rig.cli.main.main` in-process. Whatever the input: an exit code of 0 or 2 (1 only for a
device failure), never an uncaught exception, a bounded message, and nothing written on exit 2.
"""

from __future__ import annotations

import contextlib
import io
import re
import tempfile
from pathlib import Path
from typing import Any

import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from shared import field_strategy

from repo_paths import ROOT
from rig.cli.main import main
from rig.config.campaign import Capture

RIGS = ROOT / "campaigns" / "rigs"
TINY = {
    "name": "tiny",
    "sample": {"id": "T", "simulated_brdf": {"model": "lambert", "params": {"kd": 0.5}}},
    "incidence": [{"phi": 0, "theta": [30]}],
    "viewing": [{"points": [[20, 180], [40, 180]]}],
    "lamp": {"warmup_min_s": 0, "warmup_check_s": 10},
}
#: An alias bomb: `*i` stands for 9^9 strings in 9 lines.
BOMB = "bomb:\n" + "".join(
    f"  {c}: &{c} [" + ",".join([f"*{chr(ord(c) - 1)}" if c != "a" else '"lol"'] * 9) + "]\n" for c in "abcdefghi")
SENTINEL = "__FUZZ_ALIAS__"
#: Output of one command, at most (a 236-byte bomb printed 113 MB).
MAX_OUTPUT_CHARS = 20_000
FUZZ = settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])

garbage = st.recursive(
    st.one_of(st.none(), st.booleans(), st.integers(-10 ** 30, 10 ** 30),
              st.floats(allow_nan=True, allow_infinity=True), st.sampled_from([1e308, -1e308, 5e-324, 0, -1, 360]),
              st.text(max_size=30), st.just("x" * 5000), st.just("\x00\n\t")),
    lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner, max_size=3),
    max_leaves=6)


def paths(node: Any, prefix: tuple = ()) -> list[tuple]:
    """Every key path in a nested structure of dicts and lists."""
    out = [prefix] if prefix else []
    items = node.items() if isinstance(node, dict) else enumerate(node) if isinstance(node, list) else []
    for key, child in items:
        out.extend(paths(child, (*prefix, key)))
    return out


def _parent(data: Any, path: tuple) -> Any:
    for key in path[:-1]:
        data = data[key]
    return data


@st.composite
def mutated_yaml(draw, base: dict) -> str:
    """YAML text of `base` with one to three mutations."""
    data = yaml.safe_load(yaml.safe_dump(base))
    extra_text = ""
    use_bomb = False
    for _ in range(draw(st.integers(1, 3))):
        all_paths = paths(data)
        kind = draw(st.sampled_from(["delete", "replace", "replace", "add", "duplicate", "alias"]))
        if not all_paths or kind == "duplicate":
            key = draw(st.sampled_from(sorted(data))) if data else "name"
            extra_text += yaml.safe_dump({key: draw(garbage)})
            continue
        path = draw(st.sampled_from(all_paths))
        parent = _parent(data, path)
        if kind == "delete":
            del parent[path[-1]]
        elif kind == "replace":
            parent[path[-1]] = draw(garbage)
        elif kind == "alias":
            parent[path[-1]] = SENTINEL
            use_bomb = True
        elif isinstance(parent, dict):
            parent[draw(st.text(min_size=1, max_size=20))] = draw(garbage)
    text = yaml.safe_dump(data, sort_keys=False) + extra_text
    if use_bomb:
        text = BOMB + text.replace(SENTINEL, "*i")
    return text


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(argv)
        except SystemExit as exc:          # argparse: usage error
            code = exc.code
    return code, out.getvalue(), err.getvalue()


def check_outcome(code: int, out: str, err: str, *, allow_device_failure: bool = False) -> None:
    assert isinstance(code, int) and code in ((0, 1, 2) if allow_device_failure else (0, 2)), (code, err[-2000:])
    assert len(out) + len(err) < MAX_OUTPUT_CHARS, (len(out), len(err))
    assert "Traceback" not in err
    if code == 2:
        assert err.startswith("rig: error: ") and out == "", err[:500]
    if code == 1:
        assert "device" in err, err[:500]
    assert not re.search(r"\d{20,}", out), "a number of 20 digits or more in the plan (e.g. its rig time)"


def _write(folder: Path, name: str, text: str) -> Path:
    f = folder / name
    f.write_text(text, encoding="utf-8")
    return f


@FUZZ
@given(mutated_yaml(TINY))
def test_fuzz_campaign_files_through_rig_plan(text):
    with tempfile.TemporaryDirectory() as tmp:
        f = _write(Path(tmp), "c.yaml", text)
        check_outcome(*run_cli(["plan", str(f)]))


@FUZZ
@given(mutated_yaml(yaml.safe_load((RIGS / "simulated.yaml").read_text())), st.booleans())
def test_fuzz_rig_files_through_rig_plan(text, lab):
    with tempfile.TemporaryDirectory() as tmp:
        campaign = _write(Path(tmp), "c.yaml", yaml.safe_dump(TINY))
        rig = _write(Path(tmp), "r.yaml", text if not lab else
                     text.replace("simulated: true", "simulated: false"))
        check_outcome(*run_cli(["plan", str(campaign), "--rig", str(rig)]))


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_yaml(yaml.safe_load((RIGS / "example-lab.yaml").read_text())))
def test_fuzz_hardware_rig_files_through_rig_plan(text):
    with tempfile.TemporaryDirectory() as tmp:
        campaign = _write(Path(tmp), "c.yaml", yaml.safe_dump(TINY))
        check_outcome(*run_cli(["plan", str(campaign), "--rig", str(_write(Path(tmp), "r.yaml", text))]))


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_yaml(yaml.safe_load((RIGS / "simulated.yaml").read_text())))
def test_fuzz_rig_files_through_rig_devices(text):
    """The simulated rig is started for each file that validates; a device may refuse (exit 1)."""
    with tempfile.TemporaryDirectory() as tmp:
        check_outcome(*run_cli(["devices", str(_write(Path(tmp), "r.yaml", text))]), allow_device_failure=True)


CAPTURE_KEYS = ("roi_px", "bracket_stops", "target_fraction", "mode", "probe_exposure_s", "bracket_count",
                "bracket_step_stops", "max_exposures", "min_snr", "frames_per_exposure")


@st.composite
def capture_sections(draw) -> dict:
    """Mostly values inside the schema's bounds (they must run), some garbage (refused)."""
    keys = draw(st.lists(st.sampled_from(CAPTURE_KEYS), min_size=1, max_size=3, unique=True))
    return {k: draw(st.one_of(field_strategy(Capture, k), field_strategy(Capture, k), garbage)) for k in keys}


@settings(max_examples=10, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(capture_sections())
def test_fuzz_capture_section_through_rig_run(capture):
    """Defect 4 end to end: a capture section either runs to completion or is refused with nothing written."""
    with tempfile.TemporaryDirectory() as tmp:
        f = _write(Path(tmp), "c.yaml", yaml.safe_dump({**TINY, "capture": capture}))
        out = Path(tmp) / "ds"
        code, stdout, err = run_cli(["run", str(f), "--out", str(out), "--quiet"])
        check_outcome(code, stdout, err)
        assert out.exists() == (code == 0)
