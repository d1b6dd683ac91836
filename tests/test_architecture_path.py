"""docs/architecture.md's walk of one point, from the campaign YAML to brdf.csv, against the code as it runs.

The page says what a newcomer follows: a table of hops (`A → B`: module A hands the point's data to module B),
the functions each hop calls and the types the data arrives in, then the count. This runs `rig run` on the
simulated rig as the page describes it (a table campaign, a raw camera, no filter wheel; then with one) under a
profiler that records which rig function calls which, and fails when the table names a call the run no longer
makes or a module the point no longer passes, when a module holding the point's data (the CLI, the engine, the
ledger) calls another that no hop names and that is not listed here as carrying none of the point's data, or when
the count is not its table's. The caller and callee
modules are the frames' `__name__`, so a dataclass's generated `__init__` counts for the module of its class.
"""

import re
import sys
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from importlib import import_module
from pathlib import Path
from types import FrameType
from typing import Any

import pytest
import yaml

from repo_paths import RIGS, ROOT
from rig.cli.main import main

PAGE = ROOT / "docs" / "architecture.md"
PATH_HEADING = "## One point, from the campaign YAML to a row of brdf.csv"
CAMPAIGN = {
    "name": "one-series",
    "sample": {"id": "S", "simulated_brdf": {"model": "lambert", "params": {"kd": 0.5}}},
    "incidence": [{"phi": 0, "theta": [30]}],
    "viewing": [{"centred_on": "normal", "theta": [20], "phi": [0, 180]}],
    "lamp": {"warmup_min_s": 60},
}


@dataclass(frozen=True)
class Hop:
    number: int
    #: `A → B → C, D; then A → E`: the modules the data goes through (C and D both called from B), the calls
    #: one module makes in turn apart (`; then`)
    chains: tuple[tuple[tuple[str, ...], ...], ...]
    mentioned: tuple[str, ...]       # every module the row names (its column of functions names some)
    functions: tuple[str, ...]       # the calls the row names: `f`, `Class.method`, `Class` (constructed)
    types: tuple[str, ...]           # rig's types the data arrives as


def import_name(path: str) -> str:
    """`rig/acquisition/engine.py` → `rig.acquisition.engine`."""
    return path.removesuffix(".py").replace("/", ".")


def code_spans(text: str) -> list[str]:
    return re.findall(r"`([^`]+)`", text)


def called_name(span: str) -> str | None:
    """The function a code span names (`Runner(...).run()` → `Runner.run`); None for a path or an expression."""
    name = re.sub(r"\([^()]*\)", "", span)
    return name if re.fullmatch(r"[A-Za-z_]\w*(\.[A-Za-z_]\w*)?", name) else None


def path_section(page: str) -> str:
    return page.split(PATH_HEADING, 1)[1].split("\n## ", 1)[0]


def hops(section: str) -> list[Hop]:
    """The first table of the section: `| # | module | function | the point's data arrives as |`."""
    table = section.split("\n\n| # |", 1)[1].split("\n\n", 1)[0]
    found = []
    for line in table.splitlines()[2:]:
        cells = [c.strip() for c in line.strip().strip("|").split(" | ")]
        number, chain, calls, arrives = cells
        chains = tuple(tuple(tuple(import_name(p) for p in code_spans(step)) for step in part.split("→"))
                       for part in chain.split("; then"))
        mentioned = tuple(import_name(p) for p in re.findall(r"`(rig/[\w/]+\.py)`", line))
        functions = tuple(n for s in code_spans(calls) if not s.startswith("rig/") and (n := called_name(s)))
        types = tuple(t for s in code_spans(arrives) if re.fullmatch(r"[A-Z]\w*", t := s.split(" ")[0]))
        found.append(Hop(int(number), chains, mentioned, functions, types))
    return found


def stated_count(section: str) -> tuple[int, int, int]:
    hop_n, module_n, type_n = re.search(r"\*\*The count: (\d+) hops, (\d+) modules, (\d+) types\.\*\*",
                                        section).groups()
    return int(hop_n), int(module_n), int(type_n)


def counted_modules(section: str) -> list[str]:
    """The modules the count lists: `a/b`, … up to the parenthesis that names those not counted."""
    listed = section.split("The modules are those whose code handles the point's data:", 1)[1].split("(", 1)[0]
    return ["rig." + m.replace("/", ".") for m in code_spans(listed)]


def counted_types(section: str) -> list[str]:
    listed = section.split("The types are rig's own:", 1)[1].split("(the row", 1)[0]
    return code_spans(listed)


@dataclass
class Calls:
    """Every call between rig functions in the main thread: callee (module, qualified name), caller module; and
    what a holder of the point's data (HOLDERS) itself calls in other modules while it holds it."""

    made: set[tuple[str, str]] = field(default_factory=set)
    edges: set[tuple[str, str]] = field(default_factory=set)
    by_holders: set[tuple[str, str, str]] = field(default_factory=set)      # holder module, callee module, name

    def called(self, module: str, name: str) -> bool:
        return any(m == module and names(q, name) for m, q in self.made)


def names(qualname: str, name: str) -> bool:
    """Whether a table's `name` (`f`, `Class.method`, `Class` constructed) names the function `qualname`."""
    return qualname == name or qualname.endswith("." + name) or qualname == f"{name}.__init__"


ENGINE, LEDGER = "rig.acquisition.engine", "rig.acquisition.ledger"
#: The functions during which a module holds the point's data and hands it on: the CLI preparing the run, the
#: engine taking a point, the ledger keeping it and writing it.
HOLDERS = {("rig.cli.main", "cmd_run"), (ENGINE, "Runner._take_point"), (LEDGER, "Ledger.keep"),
           (LEDGER, "Ledger.write_pending")}


def module_of(frame: FrameType | None) -> str:
    return frame.f_globals.get("__name__", "") if frame is not None else ""


def qualified_name(frame: FrameType) -> str:
    """The function's qualified name; a dataclass's generated `__init__` as `Class.__init__`."""
    code = frame.f_code
    if code.co_name == "__init__" and "<locals>" in code.co_qualname and "self" in frame.f_locals:
        return f"{type(frame.f_locals['self']).__qualname__}.__init__"
    return code.co_qualname


@contextmanager
def recorded_calls() -> Iterator[Calls]:
    calls = Calls()
    holding: list[FrameType] = []          # the frames of HOLDERS' functions under way, innermost last

    def profile(frame: FrameType, event: str, _arg: Any) -> None:
        callee = module_of(frame)
        if not callee.startswith("rig."):
            return
        if event == "return":
            if holding and frame is holding[-1]:
                holding.pop()
            return
        if event != "call":
            return
        name = qualified_name(frame)
        calls.made.add((callee, name))
        caller = module_of(frame.f_back)
        if caller.startswith("rig.") and caller != callee:
            calls.edges.add((caller, callee))
            if holding and caller == module_of(holding[-1]):
                calls.by_holders.add((caller, callee, name))
        if (callee, name) in HOLDERS:
            holding.append(frame)

    previous: Callable[..., Any] | None = sys.getprofile()
    sys.setprofile(profile)
    try:
        yield calls
    finally:
        sys.setprofile(previous)


def rig_file(tmp_path: Path, *, wheel: bool) -> Path:
    rig = yaml.safe_load((RIGS / "simulated.yaml").read_text(encoding="utf-8"))
    if not wheel:
        del rig["devices"]["attenuator"], rig["attenuator"]
    path = tmp_path / "rig.yaml"
    path.write_text(yaml.safe_dump(rig), encoding="utf-8")
    return path


def run_recorded(tmp_path: Path, *, wheel: bool) -> Calls:
    campaign = tmp_path / "campaign.yaml"
    campaign.write_text(yaml.safe_dump(CAMPAIGN), encoding="utf-8")
    with recorded_calls() as calls:
        code = main(["run", str(campaign), "--rig", str(rig_file(tmp_path, wheel=wheel)),
                     "--out", str(tmp_path / "ds"), "--quiet"])
    assert code == 0
    assert len((tmp_path / "ds" / "brdf.csv").read_text(encoding="utf-8").splitlines()) == 1 + 2
    return calls


@pytest.fixture(scope="module")
def section() -> str:
    return path_section(PAGE.read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def without_wheel(tmp_path_factory) -> Calls:
    return run_recorded(tmp_path_factory.mktemp("no-wheel"), wheel=False)


def test_the_page_counts_what_its_table_lists(section):
    table = hops(section)
    hop_n, module_n, type_n = stated_count(section)
    assert [h.number for h in table] == list(range(1, len(table) + 1)) and len(table) == hop_n
    modules, types = counted_modules(section), counted_types(section)
    assert len(modules) == len(set(modules)) == module_n
    assert len(types) == len(set(types)) == type_n
    chained = {m for h in table for chain in h.chains for step in chain for m in step}
    assert chained <= set(modules) <= {m for h in table for m in h.mentioned}
    assert {t for h in table for t in h.types} == set(types)


def missing(hop: Hop, calls: Calls) -> list[str]:
    """What the row names that the run did not do: a call from one module of its chain to the next, a function
    called in one of the modules it names, a class (constructed or raised) one of them has."""
    problems = [f"hop {hop.number}: no call from {a} to {b}" for chain in hop.chains
                for callers, callees in zip(chain, chain[1:]) for a in callers for b in callees
                if (a, b) not in calls.edges]
    for name in hop.functions:
        found = any(calls.called(m, name) for m in hop.mentioned)
        if not found and "." not in name and name[0].isupper():      # a class raised, not constructed, here
            found = any(hasattr(import_module(m), name) for m in hop.mentioned)
        if not found:
            problems.append(f"hop {hop.number}: {name} not in {', '.join(hop.mentioned)}")
    return problems


def test_every_hop_of_the_table_is_a_call_the_run_makes(section, without_wheel):
    assert [p for hop in hops(section) for p in missing(hop, without_wheel)] == []


#: What a holder of the point's data calls in other modules that hands nothing of it on toward brdf.csv.
NOT_THE_POINTS_DATA = {
    ("rig.config.rigfile", "load_rig_config"): "the rig file: the rig the point is measured on",
    ("rig.session.warmup_estimate", "expected_warmup"): "the lamp's warm-up the first ETA counts",
    ("rig.acquisition.progress", "format_duration"): "the run's end, printed",
    ("rig.acquisition.progress", "end_progress_lines"): "the run's end, printed",
    ("rig.acquisition.ledger", "Ledger.started"): "a point goes ahead: the lamp-check mark counts it",
    ("rig.acquisition.moves", "Mover.start"): "the next point's move, started before this point's frames merge",
    ("rig.acquisition.eta", "Eta.done"): "the ETA counts the point done",
    # A device slow to answer on a loaded machine: the point is retried or taken again, its row as before.
    ("rig.data.dataset_writer", "DatasetWriter.event"): "the retry's event in events.jsonl",
    ("rig.acquisition.moves", "Mover.resync"): "the axes read again after a device's failure",
    ("rig.acquisition.ledger", "Ledger.rewind"): "points a pause takes back, to be measured again",
    # The CLI made these calls itself before issue 32 (commit 381cda1, whose path docs/architecture.md counts with
    # this test too); the pre-flight and the run make them now, inside hops 2 and 3.
    ("rig.config.campaign", "check_campaign_for_rig"): "a check: its verdict stops the run, nothing of it is in a row",
    ("rig.devices", "check_devices"): "a check of the rig file's devices",
    ("rig.data.output_folder", "require_new_output"): "a check of the dataset folder",
    ("rig.acquisition.diskspace", "estimate_dataset_bytes"): "the dataset's size, for the disk-space check",
    ("rig.acquisition.diskspace", "space_problem"): "the disk-space check",
    ("rig.session.connect", "open_campaign_rig"): "the rig the points are measured on",
    ("rig.session.adaptive_sampler", "sampler_for"): "an adaptive campaign's source of points (None for a table)",
}


def not_the_points_data(module: str, qualname: str) -> bool:
    """NOT_THE_POINTS_DATA, the suspenders' polls, the rig's clock (its rig time, its pace) and the point's UTC time
    stamp (`utc_now`, from the computer's clock)."""
    return (module, qualname) in NOT_THE_POINTS_DATA or module == "rig.acquisition.suspenders" or \
        module.endswith(".clock") or qualname == "utc_now"


def unlisted(section: str, calls: Calls) -> set[tuple[str, str, str]]:
    """What a holder called in another module that no hop names as a call from the holder's module (one step of
    a chain to the next) and that is not in NOT_THE_POINTS_DATA."""
    listed = {(caller, callee, name) for h in hops(section) for chain in h.chains
              for callers, callees in zip(chain, chain[1:]) for caller in callers for callee in callees
              for name in h.functions}
    return {(h, m, q) for h, m, q in calls.by_holders if not not_the_points_data(m, q)
            and not any((h, m) == (lh, lm) and names(q, n) for lh, lm, n in listed)}


def test_every_call_a_holder_makes_is_a_hop_of_the_page(section, without_wheel):
    """What the CLI, the engine or the ledger calls in another module while it holds the point's data hands it on
    (a hop of the table, or a call listed inside one) or is listed here as not doing so."""
    assert unlisted(section, without_wheel) == set()


def test_the_check_fails_on_a_call_of_the_engine_the_page_leaves_out(section, without_wheel):
    """Planted: the table without hop 7, as the page had it before this check."""
    rows = section.split("\n| 7 | ", 1)
    without_7 = rows[0] + "\n" + rows[1].split("\n", 1)[1]
    assert unlisted(without_7, without_wheel) == {(ENGINE, "rig.physics.optics", "roi_inside_spot")}


def test_every_counted_module_runs_code_for_the_point(section, without_wheel):
    ran = {m for m, _ in without_wheel.made}
    type_only = {import_name(p) for p in ("rig/planning/points.py", "rig/core/values.py")}   # dataclasses, frozen
    assert set(counted_modules(section)) - ran <= type_only


def test_a_filter_wheel_wraps_the_capturer_as_the_page_says(section, tmp_path):
    """The paragraph after the count: with a wheel, hops 5 and 6 go through `attenuation.py`."""
    assert "AttenuatingCapturer.acquire" in section and "AttenuatedAcquisition.reduce" in section
    with_wheel = run_recorded(tmp_path, wheel=True)
    attenuation = "rig.acquisition.attenuation"
    assert with_wheel.called(attenuation, "AttenuatingCapturer.acquire")
    assert with_wheel.called(attenuation, "AttenuatedAcquisition.reduce")
    assert ("rig.acquisition.engine", attenuation) in with_wheel.edges


def test_without_a_wheel_a_point_never_enters_the_attenuation_module(without_wheel):
    """The runner asks once, at its start, whether the rig has a wheel (`attenuation_for`, None here)."""
    assert {q for m, q in without_wheel.made if m == "rig.acquisition.attenuation"} == {"attenuation_for"}


def test_the_check_fails_on_a_row_the_code_no_longer_follows(section, without_wheel):
    """Planted bad rows, from the path before issue 32 (commit 381cda1): the filter wheel's `reduce_through`,
    and the engine taking the BRDF angles from the geometry itself (now the mover's `arrive` does)."""
    old_call = section.replace("`Acquisition.reduce` → `roi_statistics`", "`reduce_through` → `roi_statistics`")
    assert [p.split(" not in ")[0] for p in missing(hops(old_call)[5], without_wheel)] == ["hop 6: reduce_through"]
    mover = "`rig/acquisition/engine.py` → `rig/acquisition/moves.py` → `rig/physics/geometry.py`"
    assert mover in section
    old_chain = section.replace(mover, "`rig/acquisition/engine.py` → `rig/acquisition/moves.py`; "
                                       "then `rig/acquisition/engine.py` → `rig/physics/geometry.py`")
    assert missing(hops(old_chain)[3], without_wheel) == [
        "hop 4: no call from rig.acquisition.engine to rig.physics.geometry"]


def test_the_count_check_fails_on_a_count_the_table_does_not_add_up_to(section):
    wrong = section.replace("**The count: 12 hops,", "**The count: 11 hops,")
    assert stated_count(wrong)[0] != len(hops(wrong))
