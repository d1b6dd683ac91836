"""`rig run --resume DIR`: continue an interrupted or failed campaign in its dataset folder.

Same plan, same point ids, no duplicate rows. The campaign file must be the one
the dataset was started with (sha256 in the manifest) unless forced; the rig
configuration is the manifest's, or a new rig file's (`--rig`) once it is found to
describe the same instruments: only how each device is reached (its address, its
link's timeout) may differ, since a served rig restarts on new ports and a USB serial
adapter can come back under another name (rig.acquisition.rig_change). Points written
ahead as `point_pending` (their closing E⊥ reading never came) are appended first,
with the E⊥ they had.

The folder is locked first (one writer, rig/data/folderlock.py); everything it holds is
checked before anything is appended, and a malformed file is refused (exit 2) with
its name and line. A corrupt line in the middle of events.jsonl is refused rather
than skipped: it may be a `point_pending` record (skipping it only costs a
re-measurement) but it may as well be a `points_discarded` one, and skipping that
would bring back points measured while the lamp jumped. Only the user can tell,
so the message says which line to repair or delete.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any, NamedTuple

from rig.acquisition.execute import Prepared
from rig.acquisition.preflight import preflight
from rig.acquisition.rig_change import LINK_KEYS, instrument_difference, link_changes
from rig.config.campaign import Campaign, CampaignError, campaign_sha256, load_campaign
from rig.config.rigfile import RigConfig, load_rig_config
from rig.core import events
from rig.core.jsonfile import JsonFileError, parse_json
from rig.data.dataset_format import BRDF_COLUMNS
from rig.data.dataset_reader import complete_lines, numeric_columns, read_brdf_table
from rig.data.dataset_writer import DatasetWriter, utc_now
from rig.data.output_folder import folder_size

_TEXT_FIELDS = ("point_id", "flags", "time_utc")


class ResumeError(CampaignError):
    """The folder cannot be resumed; the message says why and what to do."""


def _rows(folder: Path) -> list[dict]:
    """The rows of brdf.csv, checked: the exact columns this version appends, finite numbers."""
    table = read_brdf_table(folder)
    if tuple(table.header) != BRDF_COLUMNS:
        raise ResumeError(f"{table.path}:1: its columns are not the ones this version of rig appends, "
                          "so rows cannot be added to it")
    numeric_columns(table)
    return table.rows


def _row_problem(row: Any) -> str | None:
    """What is wrong with a written-ahead row, or None if it can be appended as it is."""
    if not isinstance(row, dict):
        return "its row is not an object"
    missing = [c for c in BRDF_COLUMNS if c not in row]
    if missing:
        return f"its row lacks {', '.join(missing[:3])}{' …' if len(missing) > 3 else ''}"
    for column in BRDF_COLUMNS:
        value = row[column]
        if column in _TEXT_FIELDS:
            ok = isinstance(value, str)
        elif column == "exposures_s":
            ok = isinstance(value, list) and all(_finite(v) for v in value)
        else:
            ok = _finite(value)
        if not ok:
            return f"its row's {column} is {str(value)[:40]!r}"
    return None


def _finite(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _corrupt(path: Path, lineno: int, what: str) -> ResumeError:
    return ResumeError(f"{path}:{lineno}: {what}; resuming past it could lose a point written ahead or bring "
                       "back discarded ones, so nothing was changed: repair or delete that line, then resume again")


def _events(folder: Path) -> Iterator[tuple[Path, int, dict]]:
    """(file, line number, event) of every line of events.jsonl; ResumeError at a line that is not a JSON object."""
    path = folder / "events.jsonl"
    text, _ = complete_lines(path, path.read_bytes())      # reopen has cut a torn last line
    for lineno, line in enumerate(text.split("\n")[:-1], start=1):
        try:
            event = parse_json(line, path, first_line=lineno)
        except JsonFileError as exc:
            raise _corrupt(path, lineno, exc.reason) from None
        if not isinstance(event, dict):
            raise _corrupt(path, lineno, "not a JSON object")
        yield path, lineno, event


def _pending_rows(folder: Path) -> dict[str, dict]:
    """Rows written ahead in events.jsonl and not discarded later, by point id (the last one wins)."""
    pending: dict[str, dict] = {}
    for path, lineno, event in _events(folder):
        kind = event.get("event")
        if kind == events.POINT_PENDING:
            problem = _row_problem(event.get("row"))
            if problem:
                raise _corrupt(path, lineno, f"a point_pending record whose {problem.removeprefix('its ')}")
            pending[event["row"]["point_id"]] = event["row"]
        elif kind == events.POINTS_DISCARDED:
            ids = event.get("point_ids")
            if not isinstance(ids, list) or not all(isinstance(i, str) for i in ids):
                raise _corrupt(path, lineno, "a points_discarded record without a list of point ids")
            for pid in ids:
                pending.pop(pid, None)
    return pending


def _logged_batches(folder: Path, candidates: set[str]) -> list[dict]:
    """An adaptive run's `adaptive_batch` events, checked: candidate ids, four finite motor angles each."""
    logged = []
    for path, lineno, event in _events(folder):
        if event.get("event") != events.ADAPTIVE_BATCH:
            continue
        ids, motors = event.get("points"), event.get("motors_deg")
        ok = (isinstance(ids, list) and isinstance(motors, list) and len(ids) == len(motors)
              and all(isinstance(i, str) and i in candidates for i in ids)
              and all(isinstance(m, list) and len(m) == 4 and all(_finite(x) for x in m) for m in motors)
              and _finite(event.get("estimated_s")))
        if not ok:
            raise _corrupt(path, lineno, "an adaptive_batch record without candidate point ids, their motors "
                                         "and its planned time")
        logged.append(event)
    return logged


def find_campaign_file(folder: Path, info: dict) -> Path:
    """The campaign file the run was started with.

    New manifests hold its absolute path. An older, relative one is tried against the current
    folder and every parent of the dataset folder (a run started from the project root with
    `--out runs/x` has the campaign two levels up); among several candidates the one with the
    recorded sha256 wins, else the first found (resume then refuses it as changed).
    """
    recorded = info.get("file")
    if not isinstance(recorded, str) or not recorded:
        raise ResumeError(f"{folder}: its manifest names no campaign file (an imported dataset, or not "
                          "started by `rig run`): there is nothing to resume")
    path = Path(recorded)
    candidates = [path] if path.is_absolute() else [Path.cwd() / path,
                                                    *(p / path for p in folder.resolve().parents)]
    found = []
    for candidate in candidates:
        try:
            if candidate.is_file():
                if campaign_sha256(candidate) == info.get("sha256"):
                    return candidate
                found.append(candidate)
        except OSError:
            continue
    if found:
        return found[0]
    where = "" if path.is_absolute() else " (looked in the current folder and the dataset folder's parents)"
    raise ResumeError(f"{folder}: the campaign file {recorded!r} it was started with is not there{where}")


def _manifest_part(folder: Path, manifest: dict, key: str, kind: type) -> Any:
    value = manifest.get(key, kind())
    if not isinstance(value, kind):
        raise ResumeError(f"{folder / 'dataset.json'}: {key!r} is a {type(value).__name__}, "
                          f"not a {kind.__name__}; cannot resume")
    return value


def _same_instruments(folder: Path, recorded: RigConfig, rig_file: str | Path) -> tuple[RigConfig, dict]:
    """The rig file `--rig` names, if it describes the instruments the dataset was measured with, and what
    differs in how they are reached; ResumeError naming the first other difference."""
    rig = load_rig_config(rig_file)
    difference = instrument_difference(recorded, rig)
    if difference is not None:
        raise ResumeError(f"{rig_file}: {difference}: not the instruments {folder} was measured with; a resume "
                          f"with a new rig file may change only how the devices are reached "
                          f"({', '.join(LINK_KEYS)}), nothing was changed")
    return rig, link_changes(recorded, rig)


class _Recorded(NamedTuple):
    """The run a folder's manifest records, checked against the files as they are now."""

    status: Any
    campaign: Campaign
    path: Path
    changed: bool                       # the campaign file differs from the one the run started with (forced)
    rig: RigConfig
    changes: dict[str, list[Any]]       # with `--rig`: how each device is reached now (rig.acquisition.rig_change)


def _recorded(folder: Path, manifest: dict, force: bool, rig_file: str | Path | None) -> _Recorded:
    """The campaign and rig of the run in `folder`; ResumeError if it is complete, its campaign file changed
    (unless `force`), its rig configuration is not valid, or `rig_file` describes other instruments."""
    status = manifest.get("status")
    if status == "complete":
        raise ResumeError(f"{folder}: the campaign is complete; nothing to resume")
    info = _manifest_part(folder, manifest, "campaign", dict)
    rig_config = _manifest_part(folder, manifest, "rig", dict).get("config")
    path = find_campaign_file(folder, info)
    changed = campaign_sha256(path) != info.get("sha256")
    if changed and not force:
        raise ResumeError(f"{folder}: campaign file {path} changed since the run started (sha256 differs); "
                          "resuming would mix two campaigns. Use --force to resume with the file as it is now")
    campaign = load_campaign(path)
    try:
        rig = RigConfig.model_validate(rig_config)
    except ValueError as exc:
        raise ResumeError(f"{folder / 'dataset.json'}: rig.config is not a valid rig configuration "
                          f"({str(exc).splitlines()[0]})") from None
    changes: dict[str, list[Any]] = {}
    if rig_file is not None:
        rig, changes = _same_instruments(folder, rig, rig_file)
    return _Recorded(status, campaign, path, changed, rig, changes)


def _log_resume(writer: DatasetWriter, run: _Recorded, recovered: list[dict], *, force: bool,
                rig_file: str | Path | None) -> list[dict]:
    """Append the recovered written-ahead rows, log the resume (events and the manifest's `resumes`; with
    `rig_file`, the rig configuration a further resume uses); the rows the folder now holds."""
    manifest = writer.manifest
    resumes = _manifest_part(writer.dir, manifest, "resumes", list)
    for row in recovered:
        writer.append_row(row)
    if recovered:
        writer.event(events.PENDING_RECOVERED, points=len(recovered), point_ids=[r["point_id"] for r in recovered])
    done = _rows(writer.dir)
    new_rig = {} if rig_file is None else {"rig_file": str(Path(rig_file).resolve()), "rig_changes": run.changes}
    writer.event(events.RESUME, previous_status=run.status, measured_before=len(done), campaign_changed=run.changed,
                 torn_bytes_cut=writer.cut_bytes, **new_rig)
    resumes = resumes + [{"time_utc": utc_now(), "previous_status": run.status,
                          "measured_before": len(done), "forced": force and run.changed, **new_rig}]
    rig_entry = {} if rig_file is None else {           # a further resume reaches the devices where they are now
        "rig": {**manifest["rig"], "config": run.rig.model_dump(mode="json")}}
    writer.update_manifest(status="running", resumes=resumes, **rig_entry)
    (writer.dir / events.PHASE_FILE).unlink(missing_ok=True)    # the last run's: the monitor goes by the events
    return done                                                  # until this run writes its own (rig.acquisition.phase)


def prepare_resume(folder: str | Path, *, force: bool = False, rig_file: str | Path | None = None) -> Prepared:
    """Lock and check `folder`, pass the pre-flight (rig.acquisition.preflight), recover its written-ahead points
    and log the resume; `rig_file` (`--rig`) replaces the manifest's rig configuration if it describes the same
    instruments (ResumeError naming the key that differs otherwise)."""
    folder = Path(folder)
    writer = DatasetWriter.reopen(folder)
    try:
        run = _recorded(folder, writer.manifest, force, rig_file)
        done_ids = {r["point_id"] for r in _rows(folder)}
        recovered = [row for pid, row in _pending_rows(folder).items() if pid not in done_ids]
        checked = preflight(run.campaign, run.rig, folder, campaign_file=run.path, campaign_path=run.path,
                            rig_file=rig_file if rig_file is not None else folder / "dataset.json",
                            done=done_ids | {r["point_id"] for r in recovered},
                            adaptive_log=lambda candidates: _logged_batches(folder, candidates))
        unknown = done_ids - {p.point_id for p in checked.plan.points}
        if unknown and not force:
            raise ResumeError(f"{folder}: {len(unknown)} measured points are not in the campaign's plan "
                              f"(e.g. {sorted(unknown)[0]}); use --force to resume anyway")
        writer.space_needed_bytes = folder_size(folder) + (checked.space_needed_bytes or 0)   # set by preflight
        done = _log_resume(writer, run, recovered, force=force, rig_file=rig_file)
        return replace(checked, space_needed_bytes=writer.space_needed_bytes, writer=writer, done_rows=done)
    except BaseException:
        writer.close()
        raise
