"""A campaign's runs on one rig-time axis: the first `rig run` and each `--resume` (docs/dataset.md, `runs`).

Rig time continues across resumes: a resumed run starts its clock at the rig time the campaign had reached
(its `rig_time_offset_s`), so the rows' and events' rig times grow in measurement order and the manifest's
`rig_time_s` is the campaign's total, the sum of its runs'. Charts of E⊥ and of the lamp put each run on that
axis and fit a trend per run: a resume may come with a lamp switched off for a night, and a line drawn across
the gap would be no drift of either run.

Datasets written before the `runs` list restarted their rig time at 0 at each resume; `runs_of` places each of
their runs after the previous one's last rig time, so that they read the same way.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from rig.config.campaign import Lamp
from rig.config.rigfile import RigConfig
from rig.core import events as kinds  # the kinds' names; `events` names a dataset's records here
from rig.planning.estimate import WarmupEstimate, warmup_estimate

#: Events that end a warm-up (rig.acquisition.warmup), with its `warmup_s` and `change_rel`.
WARMUP_ENDS = (kinds.WARMUP_STABLE, kinds.WARMUP_NOT_STABLE)


def _number(value: Any) -> float | None:
    ok = isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)
    return float(value) if ok else None


@dataclass(frozen=True)
class WarmUp:
    """One warm-up of the lamp: when it ended (campaign rig time), how long it took, whether E⊥ was stable."""
    end_s: float
    warmup_s: float
    stable: bool
    change_rel: float | None


@dataclass
class Run:
    """One run of the campaign: its events' readings on the campaign's rig-time axis."""
    index: int
    offset_s: float                       # campaign rig time at its start
    end_s: float                          # the latest campaign rig time it wrote
    resumed: bool
    warmups: list[WarmUp] = field(default_factory=list)
    illuminance: list[tuple[float, float, float | None]] = field(default_factory=list)   # (t, E⊥ lx, u lx)
    lamp: list[tuple[float, float | None, float | None]] = field(default_factory=list)   # (t, A, V)

    @property
    def rig_time_s(self) -> float:
        return self.end_s - self.offset_s


def continuous(manifest: Mapping[str, Any]) -> bool:
    """Whether the dataset's rig times continue across resumes (its manifest lists its runs)."""
    return isinstance(manifest.get("runs"), list)


def rig_time_shifts(manifest: Mapping[str, Any]) -> list[float] | None:
    """What to add to each run's recorded rig times: None for an old dataset (each run is placed after the
    previous one); else the `rig_time_shift_s` of the runs recorded before rig time continued (0 for the others)."""
    if not continuous(manifest):
        return None
    return [_number(r.get("rig_time_shift_s")) or 0.0 for r in manifest["runs"] if isinstance(r, Mapping)]


def runs_of(manifest: Mapping[str, Any], events: Iterable[Mapping[str, Any]]) -> list[Run]:
    """The campaign's runs from its events, split at each `resume` event, on one rig-time axis.

    A resume whose rig never came up wrote no rig time: it is no run. The runs of an old dataset (no `runs` in
    its manifest) each start where the previous one ended."""
    shifts = rig_time_shifts(manifest)
    runs: list[Run] = []
    current: Run | None = None
    shift = reached = 0.0
    for event in events:
        kind = event.get("event")
        if kind == kinds.RESUME:
            reached = current.end_s if current is not None else reached
            current = None
            continue
        t = _number(event.get("rig_time_s"))
        if t is None:
            continue
        if current is None:
            k = len(runs)
            shift = reached if shifts is None else (shifts[k] if k < len(shifts) else 0.0)
            start = reached if k else 0.0
            current = Run(k, start, start, k > 0)
            runs.append(current)
        t += shift
        current.end_s = max(current.end_s, t)
        _note(current, kind, event, t)
    return runs


def _note(run: Run, kind: Any, event: Mapping[str, Any], t: float) -> None:
    """What a run's charts and warm-up list keep of one event at campaign rig time `t`."""
    if kind == kinds.ILLUMINANCE and (lx := _number(event.get("illuminance_normal_lx"))) is not None:
        run.illuminance.append((t, lx, _number(event.get("u_lx"))))
    elif kind in (kinds.LAMP_ON, *WARMUP_ENDS):
        run.lamp.append((t, _number(event.get("current_a")),
                         _number(event.get("voltage_v", event.get("lamp_voltage_v")))))
        if kind in WARMUP_ENDS and (w := _number(event.get("warmup_s"))) is not None:
            run.warmups.append(WarmUp(t, w, kind == kinds.WARMUP_STABLE, _number(event.get("change_rel"))))


def read_events(folder: Path) -> list[dict[str, Any]]:
    """The events of `folder`'s events.jsonl that parse as objects (a torn or bad line is left out: the
    runs it would place are only a chart's)."""
    try:
        text = (folder / "events.jsonl").read_text(encoding="utf-8", errors="replace")
    except OSError:
        return []
    events = []
    for line in text.split("\n"):
        try:
            event = json.loads(line) if line else None
        except ValueError:
            continue
        if isinstance(event, dict):
            events.append(event)
    return events


def reached_s(manifest: Mapping[str, Any], events: Iterable[Mapping[str, Any]],
              rows: Sequence[Mapping[str, Any]]) -> float:
    """The campaign rig time reached so far: where a resumed run's clock starts. The latest of the manifest's
    total, the runs' ends and the rows' rig times (a killed run wrote no total, and its last rows may come after
    its last event)."""
    ends = [r.end_s for r in runs_of(manifest, events)]
    rows_s = [t for r in rows if (t := _number(_float(r.get("rig_time_s")))) is not None] if continuous(manifest) \
        else []
    total = _number(manifest.get("rig_time_s")) if continuous(manifest) else None
    return max([0.0, *ends, *rows_s, *([total] if total is not None else [])])


def _float(value: Any) -> Any:
    """A brdf.csv cell (text) or a number as a float where it is one."""
    try:
        return float(value)
    except (TypeError, ValueError):
        return None


def _legacy_runs(manifest: Mapping[str, Any], events: Sequence[Mapping[str, Any]]) -> list[dict[str, Any]]:
    """The runs of a dataset written before rig time continued, as `runs` entries: each with the
    `rig_time_shift_s` that places its rig times on the campaign's axis (it restarted at 0)."""
    resumes = [r for r in _list(manifest.get("resumes")) if isinstance(r, Mapping)]
    entries = []
    for run in runs_of(manifest, events):
        ended = resumes[run.index].get("previous_status") if run.index < len(resumes) else None
        entries.append({"run": run.index, "resumed": run.resumed, "rig_time_offset_s": run.offset_s,
                        "rig_time_s": run.rig_time_s, "rig_time_shift_s": run.offset_s,
                        "status": ended if isinstance(ended, str) else "unknown",
                        "warmups": [_warmup_entry(w) for w in run.warmups]})
    return entries


def _list(value: Any) -> list:
    """A manifest's list, or [] where it is something else (a hand-edited manifest)."""
    return value if isinstance(value, list) else []


def _warmup_entry(w: WarmUp) -> dict[str, Any]:
    return {"end_rig_time_s": w.end_s, "warmup_s": w.warmup_s, "stable": w.stable, "change_rel": w.change_rel}


class WarmUpEnd(Protocol):
    """How a warm-up ended (rig.acquisition.warmup.WarmedUp, a frozen dataclass: read-only)."""

    @property
    def lamp_voltage_v(self) -> float: ...
    @property
    def warmup_s(self) -> float: ...
    @property
    def stable(self) -> bool: ...
    @property
    def change_rel(self) -> float: ...


class RunRecorder:
    """The manifest's `runs` while a run goes: its entry when it starts, each warm-up as it ends, how it ended.

    `offset_s` is the campaign rig time the run starts at (0 for the first): the engine's clock adds it."""

    def __init__(self, writer: Any, done_rows: Sequence[Mapping[str, Any]], lamp: Lamp, rig: RigConfig,
                 expected: WarmupEstimate | None = None):
        """`writer`: the dataset's (rig.data.dataset_writer.DatasetWriter); `done_rows`: the rows already in it
        (a resume); `expected`: the warm-up the run expects (default: rig.planning.estimate's for `lamp` on
        `rig`, from the earlier runs' warm-ups in this dataset where there are some), recorded for the monitor
        and the ETA."""
        self.writer = writer
        manifest = writer.manifest
        resumed = bool(manifest.get("resumes")) or bool(done_rows)
        events = read_events(writer.dir) if resumed else []
        self.offset_s = reached_s(manifest, events, done_rows) if resumed else 0.0
        runs = manifest["runs"] if continuous(manifest) else _legacy_runs(manifest, events)
        self.runs = closed_runs(runs, self.offset_s)
        past = [w["warmup_s"] for r in self.runs for w in _list(r.get("warmups"))[:1]
                if isinstance(w, Mapping) and _number(w.get("warmup_s")) is not None]
        self.expected = expected or warmup_estimate(lamp, rig, past, " in this dataset")
        self.runs.append({"run": len(self.runs), "started_utc": _utc(manifest), "resumed": resumed,
                          "rig_time_offset_s": self.offset_s, "rig_time_s": 0.0, "status": "running",
                          "warmups": [], "expected_warmup": self.expected.as_record()})
        writer.update_manifest(runs=self.runs)

    def warmed(self, warm: WarmUpEnd, end_s: float) -> float:
        """A warm-up ended at campaign rig time `end_s`: into the manifest now (a killed run keeps it); returns
        the lamp voltage once warm."""
        self.runs[-1]["warmups"].append(_warmup_entry(WarmUp(end_s, warm.warmup_s, warm.stable, warm.change_rel)))
        self.writer.update_manifest(runs=self.runs)
        return warm.lamp_voltage_v

    def ended(self, status: str, rig_time_s: float) -> list[dict[str, Any]]:
        """The runs with this one ended at campaign rig time `rig_time_s`, for the manifest's last update."""
        self.runs[-1].update(status=status, rig_time_s=rig_time_s - self.offset_s)
        return self.runs


def _utc(manifest: Mapping[str, Any]) -> str | None:
    """When this run starts: the last resume's time, else the dataset's creation."""
    resumes = _list(manifest.get("resumes"))
    last = resumes[-1] if resumes and isinstance(resumes[-1], Mapping) else {}
    return last.get("time_utc") or manifest.get("created_utc")


def closed_runs(runs: Sequence[Any], reached: float) -> list[dict[str, Any]]:
    """The manifest's runs with a last one left `running` (its process was killed) closed at `reached`."""
    out = [dict(r) for r in runs if isinstance(r, Mapping)]
    if out and out[-1].get("status") == "running":
        offset = _number(out[-1].get("rig_time_offset_s")) or 0.0
        out[-1].update(status="abandoned", rig_time_s=max(reached - offset, 0.0))
    return out
