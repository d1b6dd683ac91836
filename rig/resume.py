"""`rig run --resume DIR`: continue an interrupted or failed campaign in its dataset folder.

Same plan, same point ids, no duplicate rows. The campaign file must be the one
the dataset was started with (sha256 in the manifest) unless forced; the rig
configuration is the manifest's. Points written ahead as `point_pending` (their
closing E⊥ reading never came) are appended first, with the E⊥ they had.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path

from rig.campaign import Campaign, CampaignError, campaign_sha256, load_campaign
from rig.dataset import DatasetWriter, utc_now
from rig.plan import Plan, build_plan
from rig.rigconfig import RigConfig


class ResumeError(CampaignError):
    """The folder cannot be resumed; the message says why and what to do."""


@dataclass
class Resumption:
    writer: DatasetWriter
    campaign: Campaign
    campaign_path: Path
    rig: RigConfig
    plan: Plan
    done_rows: list[dict]


def _rows(folder: Path) -> list[dict]:
    with open(folder / "brdf.csv", newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def _pending_rows(folder: Path) -> dict[str, dict]:
    """Rows written ahead in events.jsonl and not discarded later, by point id (the last one wins)."""
    pending: dict[str, dict] = {}
    with open(folder / "events.jsonl", encoding="utf-8") as fh:
        for line in fh:
            event = json.loads(line)
            if event.get("event") == "point_pending":
                pending[event["row"]["point_id"]] = event["row"]
            elif event.get("event") == "points_discarded":
                for pid in event["point_ids"]:
                    pending.pop(pid, None)
    return pending


def prepare_resume(folder: str | Path, *, force: bool = False) -> Resumption:
    folder = Path(folder)
    writer = DatasetWriter.reopen(folder)
    try:
        manifest = writer.manifest
        status = manifest.get("status")
        if status == "complete":
            raise ResumeError(f"{folder}: the campaign is complete; nothing to resume")
        info = manifest.get("campaign", {})
        path = Path(info.get("file") or "")
        if not info.get("file") or not path.is_file():
            raise ResumeError(f"{folder}: the campaign file {info.get('file')!r} it was started with is not there")
        changed = campaign_sha256(path) != info.get("sha256")
        if changed and not force:
            raise ResumeError(f"{folder}: campaign file {path} changed since the run started (sha256 differs); "
                              "resuming would mix two campaigns. Use --force to resume with the file as it is now")
        campaign = load_campaign(path)
        rig = RigConfig.model_validate(manifest["rig"]["config"])
        plan = build_plan(campaign, rig)
        done = _rows(folder)
        done_ids = {r["point_id"] for r in done}
        unknown = done_ids - {p.point_id for p in plan.points}
        if unknown and not force:
            raise ResumeError(f"{folder}: {len(unknown)} measured points are not in the campaign's plan "
                              f"(e.g. {sorted(unknown)[0]}); use --force to resume anyway")
        recovered = [row for pid, row in _pending_rows(folder).items() if pid not in done_ids]
        for row in recovered:
            writer.append_row(row)
        if recovered:
            writer.event("pending_recovered", points=len(recovered),
                         point_ids=[r["point_id"] for r in recovered])
        done = _rows(folder)
        writer.event("resume", previous_status=status, measured_before=len(done), campaign_changed=changed,
                     torn_bytes_cut=writer.cut_bytes)
        resumes = manifest.get("resumes", []) + [{"time_utc": utc_now(), "previous_status": status,
                                                  "measured_before": len(done), "forced": force and changed}]
        writer.update_manifest(status="running", resumes=resumes)
        return Resumption(writer, campaign, path, rig, plan, done)
    except BaseException:
        writer.close()
        raise
