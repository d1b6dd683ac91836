"""A plain clone is self-contained: nothing reads outside the repository, the vendored test data
is intact and licensed, and the contracts in docs/ say what the code does."""

from __future__ import annotations

import hashlib
import json
import re
import typing
from pathlib import Path

import pytest
from annotated_types import Ge, Gt, Le, Lt
from pydantic import BaseModel

from repo_paths import ROOT
from rig.config import campaign as campaign_module
from rig.data.dataset_format import BRDF_COLUMNS, CONVENTIONS, SKIPPED_COLUMNS, UNITS
from rig.data.dataset_writer import DatasetWriter
from rig.planning.points import SKIP_REASONS

DOCS = ROOT / "docs"
CODE_FOLDERS = ("rig", "drivers", "simulators", "tests", "benchmarks")
#: Paths into the development workspace beside the repository, which a user's clone does not have.
OUTSIDE = re.compile(r"\.\./shared|\bshared/(?:spec|data|reference)\b|[\"']shared[\"']|parents\[2\]|/work/")


def python_files() -> list[Path]:
    return sorted(p for folder in CODE_FOLDERS for p in (ROOT / folder).rglob("*.py")
                  if "__pycache__" not in p.parts)


def test_no_code_reads_outside_the_repository():
    this = Path(__file__).resolve()
    hits = [f"{path.relative_to(ROOT)}:{n}: {line.strip()}"
            for path in python_files() if path.resolve() != this
            for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), start=1) if OUTSIDE.search(line)]
    assert not hits, "paths outside the repository:\n" + "\n".join(hits)


def test_the_outside_pattern_catches_what_it_must():
    up = ".."   # written apart, so that this file's own lines are no hits of the before-stop grep
    for line in ('CEA = ROOT.parent / "shared" / "data"',
                 "see shared/spec/geometry.md",
                 "Path(__file__).parents[2]",
                 f"open('{up}/shared/x')",
                 "/work/shared/data/cea-retro"):
        assert OUTSIDE.search(line), line
    assert not OUTSIDE.search("def shared_lamp(peer, world):  # the shared driver")


def test_manifest_conventions_name_a_document_that_ships_with_rig(tmp_path):
    document = CONVENTIONS.split()[0]
    assert document == "docs/geometry.md" and (ROOT / document).is_file()
    writer = DatasetWriter(tmp_path / "ds", {})
    writer.close()
    assert json.loads((tmp_path / "ds" / "dataset.json").read_text())["conventions"] == CONVENTIONS


def test_vendored_cea_data_is_intact_and_licensed(cea_dir):
    provenance = (cea_dir / "PROVENANCE.md").read_text(encoding="utf-8")
    assert "MPL-2.0" in provenance or "Mozilla Public License" in provenance
    for name in ("retro-3M-yellow.alta", "retro-gray-tape.alta"):
        row = next(line for line in provenance.splitlines() if line.startswith(f"| `{name}`"))
        listed = re.search(r"`([0-9a-f]{64})`", row).group(1)
        assert hashlib.sha256((cea_dir / name).read_bytes()).hexdigest() == listed, name
    assert "Belcour" in (cea_dir / "README.md").read_text(encoding="utf-8")       # the attribution that came with it
    assert (cea_dir / "LICENSE-MPL-2.0").read_text(encoding="utf-8").startswith("Mozilla Public License Version 2.0")


# -- docs/dataset.md and docs/geometry.md against the code ----------------------------------------

def table_rows(text: str) -> dict[str, list[str]]:
    """Markdown table rows whose first cell is a `code` name: name → the other cells."""
    rows = {}
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        name = re.fullmatch(r"`([\w.\[\]]+)`", cells[0]) if line.startswith("|") else None
        if name:
            rows[name.group(1)] = cells[1:]
    return rows


def test_dataset_doc_lists_the_columns_in_order_with_their_units():
    text = (DOCS / "dataset.md").read_text(encoding="utf-8")
    section = text[text.index("## brdf.csv"):text.index("**Flags**")]
    rows = table_rows(section)
    assert list(rows) == list(BRDF_COLUMNS)
    for column, unit in UNITS.items():
        assert rows[column][0] == unit, column
    assert f"Header `{','.join(SKIPPED_COLUMNS)}`" in text


def event_kinds_in_code() -> set[str]:
    """Every event kind rig, its drivers and simulators write to events.jsonl: the named constants of
    rig.core.events, where every writer takes them from (tests/test_structure.py checks that no module
    writes one as a bare string), apart from the run's phases and their file (phase.json, documented apart)."""
    from rig.core import events

    named = {value for name, value in vars(events).items() if name.isupper() and isinstance(value, str)}
    return named - set(events.PHASES) - {events.PHASE_FILE}


def test_dataset_doc_names_every_event_kind():
    text = (DOCS / "dataset.md").read_text(encoding="utf-8")
    section = text[text.index("## events.jsonl"):text.index("## dataset.json")]
    kinds = event_kinds_in_code()
    assert {"point_pending", "safe_state", "retry", "warmup_not_stable"} <= kinds     # the search finds them
    assert not {k for k in kinds if f"`{k}`" not in section}


@pytest.mark.parametrize("doc", ["geometry.md", "dataset.md"])
def test_docs_name_every_skip_reason(doc):
    text = (DOCS / doc).read_text(encoding="utf-8")
    assert not [r for r in SKIP_REASONS if f"`{r}" not in text]


# -- docs/campaign.md against rig.config.campaign ---------------------------------------------------------

def campaign_keys(model: type[BaseModel] = campaign_module.Campaign, prefix: str = "") -> dict:
    """Dotted key → pydantic field of every campaign key, nested sections and list entries included."""
    keys = {}
    for name, field in model.model_fields.items():
        key = prefix + name
        keys[key] = field
        for sub in nested_models(field.annotation):
            keys.update(campaign_keys(sub, key + ("[]." if typing.get_origin(field.annotation) is list else ".")))
    return keys


def nested_models(annotation) -> list[type[BaseModel]]:
    """The models inside a field's type (Optional, list and tagged unions unwrapped)."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return [annotation]
    return [m for arg in typing.get_args(annotation) for m in nested_models(arg)]


BOUND_SIGNS = {Ge: ("≥", "ge"), Gt: (">", "gt"), Le: ("≤", "le"), Lt: ("<", "lt")}


def documented_bounds(cell: str) -> set[tuple[str, float]]:
    return {(sign, float(number)) for sign, number in re.findall(r"(≥|>|≤|<)\s*(\d[\d.]*(?:e\d+)?)", cell)}


def test_campaign_doc_lists_every_key():
    rows = table_rows((DOCS / "campaign.md").read_text(encoding="utf-8"))
    keys = campaign_keys()
    # a section (`capture`, `sample.simulated_brdf`, …) is documented by its keys; a list (`incidence`) by a row too
    sections = {k for k, f in keys.items()
                if nested_models(f.annotation) and typing.get_origin(f.annotation) is not list}
    assert sorted(set(keys) - sections - set(rows)) == []
    assert sorted(set(rows) - set(keys)) == []


def test_campaign_doc_gives_the_defaults_and_bounds_of_the_code():
    rows = table_rows((DOCS / "campaign.md").read_text(encoding="utf-8"))
    for key, field in campaign_keys().items():
        if key not in rows:
            continue
        default, allowed = rows[key][0], rows[key][1]
        if field.is_required():
            assert default == "required", key
        elif isinstance(field.default, bool):
            assert default == str(field.default).lower(), key
        elif isinstance(field.default, (int, float)):
            assert float(default) == pytest.approx(field.default, rel=1e-12), key
        elif isinstance(field.default, str):
            assert default == (field.default or '""'), key
        numeric = {(BOUND_SIGNS[type(m)][0], float(getattr(m, BOUND_SIGNS[type(m)][1])))
                   for m in field.metadata if type(m) in BOUND_SIGNS}
        if numeric:
            assert documented_bounds(allowed) == numeric, key
        literal = typing.get_origin(field.annotation) is typing.Literal
        for choice in typing.get_args(field.annotation) if literal else ():
            assert f"`{choice}`" in allowed, (key, choice)
