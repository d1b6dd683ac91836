"""The warm-up `rig plan` and `rig run` expect (rig.planning.estimate says the rule and the sources).

On the simulated rig the lamp model is the simulator itself: its seeded lamp and meter are run through the
warm-up rule in simulated time (a fraction of a second of wall time), so the estimate is the warm-up the run
will have. On a real rig the last warm-ups of the same rig recorded in the datasets beside the campaign's output
folder (their manifests' `runs`, docs/dataset.md) stand for the next one.
"""

from __future__ import annotations

import json
from pathlib import Path

from rig.acquisition.warmup import warm_up
from rig.config.campaign import Campaign
from rig.config.rigfile import RigConfig
from rig.planning.estimate import WarmupEstimate, warmup_estimate
from rig.session.connect import open_campaign_rig

#: Dataset folders looked at for earlier warm-ups (the newest), at most.
FOLDERS_LOOKED_AT = 50


def simulated_warmup(campaign: Campaign, rig: RigConfig) -> WarmupEstimate:
    """The warm-up of the simulated rig under the campaign's rule: the rig started as `rig run` starts it and
    warmed up, unpaced (RIG_SIM_PACE slows runs, not this)."""
    with open_campaign_rig(campaign, rig) as dev:
        if hasattr(dev.clock, "pace"):
            dev.clock.pace = 0.0
        t0 = dev.clock.now()
        dev.identities()
        try:
            done = warm_up(campaign.lamp, rig, dev, dev.clock.sleep, lambda: dev.clock.now() - t0,
                           lambda kind, **fields: None, lambda message: None)
        finally:
            dev.safe_state()
    return WarmupEstimate(done.warmup_s, f"the simulated rig's lamp and meter (seed {rig.simulation.seed}) "
                                         "through the warm-up rule")


def past_warmups_s(where: Path, rig_name: str) -> list[float]:
    """The first warm-up of each run of rig `rig_name` in the dataset folders in `where`, oldest first."""
    found: list[tuple[str, float]] = []
    try:
        folders = sorted((p for p in where.iterdir() if (p / "dataset.json").is_file()),
                         key=lambda p: (p / "dataset.json").stat().st_mtime)[-FOLDERS_LOOKED_AT:]
    except OSError:
        return []
    for folder in folders:
        try:
            manifest = json.loads((folder / "dataset.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        rig = manifest.get("rig") if isinstance(manifest, dict) else None
        runs = manifest.get("runs") if isinstance(manifest, dict) else None
        if not isinstance(rig, dict) or rig.get("name") != rig_name or not isinstance(runs, list):
            continue
        for run in runs:
            warmups = run.get("warmups") if isinstance(run, dict) else None
            first = warmups[0] if isinstance(warmups, list) and warmups and isinstance(warmups[0], dict) else {}
            seconds = first.get("warmup_s")
            if isinstance(seconds, (int, float)) and not isinstance(seconds, bool) and seconds > 0:
                found.append((str(run.get("started_utc") or ""), float(seconds)))
    return [s for _, s in sorted(found)]


def expected_warmup(campaign: Campaign, rig: RigConfig) -> WarmupEstimate:
    """The warm-up the campaign's run will need on `rig`: replayed on the simulated rig; else the last
    warm-ups of this rig found beside the campaign's output folder; else the rule's least."""
    if rig.simulated:
        return simulated_warmup(campaign, rig)
    where = Path(campaign.output.dir).parent
    return warmup_estimate(campaign.lamp, rig, past_warmups_s(where, rig.name), f" in {where}/")
