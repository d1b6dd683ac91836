"""The structure check of issue 32, on the repository's own files (nothing outside it is read): one
DiskFullError, one Motors and one grazing limit; the capture path chosen once (at most one isinstance on the
calibrated path in rig/acquisition); no bench or soak module in the runtime packages; a docstring in every
package `__init__` saying what the package owns; every event kind of events.jsonl written and read by its name in
rig.core.events, never as a bare string; no test file importing another (the helpers several use are in
tests/shared.py). The layers and no-cycle contracts are import-linter's (.ci/checks)."""

import ast
import re
from collections.abc import Iterator
from pathlib import Path

import pytest

from repo_paths import ROOT
from rig.core import events

#: The installed package: rig/, with drivers/ and simulators/ as rig.drivers and rig.simulators.
PACKAGE_DIRS = (ROOT / "rig", ROOT / "drivers", ROOT / "simulators")
#: The packages a measurement runs in: method studies (rig.bench) and the soak (tests/) stay out of them.
RUNTIME = (ROOT / "rig" / "session", ROOT / "rig" / "acquisition")
#: A raw camera's calibration file (its flat field) is looked up on the raw path: not a choice of capture path.
NOT_THE_CALIBRATED_PATH = {"CalibratedSensorInfo"}


def modules() -> Iterator[Path]:
    for folder in PACKAGE_DIRS:
        yield from sorted(p for p in folder.rglob("*.py") if "__pycache__" not in p.parts)


def tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(encoding="utf-8"), filename=str(path))


def defined(node: ast.stmt) -> list[str]:
    """The names a module-level statement defines: a class, a function, or an assignment (a type alias)."""
    if isinstance(node, ast.ClassDef | ast.FunctionDef):
        return [node.name]
    targets = node.targets if isinstance(node, ast.Assign) else [node.target] if isinstance(node, ast.AnnAssign) else []
    return [t.id for t in targets if isinstance(t, ast.Name)]


def definitions(name: str) -> list[str]:
    """Where `name` is defined at module level."""
    return [f"{path.relative_to(ROOT)}:{node.lineno}" for path in modules() for node in tree(path).body
            if name in defined(node)]


@pytest.mark.parametrize("name", ["DiskFullError", "Motors", "GRAZING_LIMIT_DEG"])
def test_defined_once(name):
    assert len(definitions(name)) == 1, definitions(name)


def test_the_grazing_limit_is_written_once():
    """The campaign's default `limits.grazing_limit_deg` is the physics' GRAZING_LIMIT_DEG, not a second 88.0."""
    found = [f"{path.relative_to(ROOT)}:{node.lineno}" for path in modules() for node in ast.walk(tree(path))
             if isinstance(node, ast.Constant) and isinstance(node.value, float) and node.value == 88.0]
    assert found == definitions("GRAZING_LIMIT_DEG")


def names_in(node: ast.expr) -> set[str]:
    return {n.id for n in ast.walk(node) if isinstance(n, ast.Name)} | \
        {n.attr for n in ast.walk(node) if isinstance(n, ast.Attribute)}


def calibrated_path_checks() -> list[str]:
    """Every `isinstance(x, Calibrated…)` in rig/acquisition that asks which capture path a point takes."""
    found = []
    for path in sorted((ROOT / "rig" / "acquisition").rglob("*.py")):
        for node in ast.walk(tree(path)):
            if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "isinstance" \
                    and len(node.args) == 2:
                asked = {n for n in names_in(node.args[1]) if n.startswith("Calibrated")} - NOT_THE_CALIBRATED_PATH
                if asked:
                    found.append(f"{path.relative_to(ROOT)}:{node.lineno} {sorted(asked)}")
    return found


def test_the_capture_path_is_chosen_once():
    assert len(calibrated_path_checks()) <= 1, calibrated_path_checks()


def test_no_bench_or_soak_module_in_the_runtime_packages():
    found = [str(p.relative_to(ROOT)) for folder in RUNTIME for p in folder.rglob("*.py")
             if "bench" in p.stem or "soak" in p.stem]
    assert found == []


def test_every_package_says_what_it_owns():
    packages = [p for folder in PACKAGE_DIRS for p in sorted(folder.rglob("__init__.py"))
                if "__pycache__" not in p.parts]
    assert len(packages) >= 15
    bare = [str(p.relative_to(ROOT)) for p in packages if not (ast.get_docstring(tree(p)) or "").strip()]
    assert bare == []


#: The calls that write an event: a run's `event`/`_event`/`event_synced_behind`, a driver's `events` sink, the
#: retry's `on_retry`, the held-events buffer's `_hold`.
EMITTERS = re.compile(r"event|^on_retry$|^_hold$")
#: Every kind rig.core.events names (its values are the on-disk format).
KINDS = {value for name, value in vars(events).items() if name.isupper() and isinstance(value, str)}


def _callee(func: ast.expr) -> str:
    return func.id if isinstance(func, ast.Name) else func.attr if isinstance(func, ast.Attribute) else ""


def _kind_of_record(node: ast.expr) -> bool:
    """`record.get("event")` or `record["event"]`: a record's kind, read back."""
    if isinstance(node, ast.Call) and _callee(node.func) == "get" and node.args:
        key = node.args[0]
    elif isinstance(node, ast.Subscript):
        key = node.slice
    else:
        return False
    return isinstance(key, ast.Constant) and key.value == "event"


def _strings(node: ast.expr | None) -> list[ast.Constant]:
    """The string literals `node` is, or chooses between (a conditional, a tuple or set of them)."""
    if isinstance(node, ast.Constant) and isinstance(node.value, str):
        return [node]
    if isinstance(node, ast.IfExp):
        return _strings(node.body) + _strings(node.orelse)
    if isinstance(node, ast.Tuple | ast.List | ast.Set):
        return [c for e in node.elts for c in _strings(e)]
    return []


def bare_event_kinds(module: ast.Module) -> list[tuple[int, str]]:
    """Event kinds `module` spells as string literals (line, kind): the first argument of an event-writing call, a
    dict literal's "event", a comparison with a record's kind, or a known kind compared with a variable `kind`."""
    found: list[ast.Constant] = []
    for node in ast.walk(module):
        if isinstance(node, ast.Call) and node.args and EMITTERS.search(_callee(node.func)):
            found += _strings(node.args[0])
        elif isinstance(node, ast.Dict):
            found += [c for k, v in zip(node.keys, node.values, strict=True)
                      if isinstance(k, ast.Constant) and k.value == "event" for c in _strings(v)]
        elif isinstance(node, ast.Compare):
            sides = [node.left, *node.comparators]
            if any(_kind_of_record(side) for side in sides):
                found += [c for side in sides for c in _strings(side)]
            elif any(isinstance(side, ast.Name) and side.id == "kind" for side in sides):
                found += [c for side in sides for c in _strings(side) if c.value in KINDS]
    return sorted((c.lineno, c.value) for c in found)


def test_event_kinds_are_written_by_their_names():
    """rig.core.events is the one place an event kind is spelled; everyone else writes and reads it by name."""
    found = [f"{path.relative_to(ROOT)}:{line} {kind!r}" for path in modules()
             if path != ROOT / "rig" / "core" / "events.py" for line, kind in bare_event_kinds(tree(path))]
    assert found == []


def test_the_event_kind_check_finds_a_bare_string():
    sample = ast.parse('''
writer.event("filter", device="attenuator")
self.events("watchdog_expired" if expired else events.WATCHDOG_OFF, device=name)
on_retry("retry", device=device)
record = {"time_utc": now, "event": "resume"}
if e.get("event") in ("warmup_stable", events.WARMUP_NOT_STABLE): pass
if kind == "lamp_on": pass
writer.event(events.FILTER, what="the names are fine")
if kind == "board": pass
''')
    assert bare_event_kinds(sample) == [(2, "filter"), (3, "watchdog_expired"), (4, "retry"), (5, "resume"),
                                        (6, "warmup_stable"), (7, "lamp_on")]


def imported_test_modules(module: ast.Module) -> list[tuple[int, str]]:
    """The test modules and conftest files `module` imports (line, module), at any depth: `import test_x`,
    `from test_x import y`, `from tests.folder.test_x import y`, `from .test_x import y`, `from . import test_x`,
    `from conftest import y` (a conftest is pytest's to load: which one `import conftest` finds depends on the
    order of sys.path)."""
    found = []
    for node in ast.walk(module):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            names = ["." * node.level + node.module] if node.module else []
            if node.level:
                names += ["." * node.level + alias.name for alias in node.names]
        else:
            continue
        found += [(node.lineno, name) for name in names
                  if any(part.startswith("test_") or part == "conftest" for part in name.lstrip(".").split("."))]
    return sorted(found)


def test_no_test_file_imports_another():
    """Issue 32: a test module imported by another runs its module-level code twice and hands its tests to a second
    namespace, and is found only while pytest has put its folder on sys.path; the helpers several test files use
    are in tests/shared.py, which every test folder can import (`pythonpath = ["tests"]`)."""
    found = [f"{path.relative_to(ROOT)}:{line} {name}" for path in sorted((ROOT / "tests").rglob("*.py"))
             if "__pycache__" not in path.parts for line, name in imported_test_modules(tree(path))]
    assert found == []


def test_the_test_import_check_finds_each_form():
    sample = ast.parse('''
from test_runner import run, small_campaign
import json, test_rows
def helper():
    from test_folder import Folder
from tests.acquisition.test_runner import events
from .test_fit import views_around_lobes
from . import test_predict, shared
from shared import Folder, warm
from repo_paths import ROOT
import pytest_timeout
from rig.cli.main import main
from conftest import Replay
import conftest_helpers
''')
    assert imported_test_modules(sample) == [(2, "test_runner"), (3, "test_rows"), (5, "test_folder"),
                                             (6, "tests.acquisition.test_runner"), (7, ".test_fit"),
                                             (8, ".test_predict"), (13, "conftest")]
