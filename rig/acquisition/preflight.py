"""The checks every run passes before any device is opened or anything is written: a new run and a resume alike;
what passes is the run itself (`Prepared`, rig.acquisition.execute), ready to `.run(...)`.

One sequence, so that `rig run`, `rig run --resume`, the benches and the tests refuse the same inputs with the same
messages: the campaign against the rig (rig.config.campaign.check_campaign_for_rig), the plan (a mandatory pair of
an adaptive campaign the rig cannot measure, a campaign with no measurable point), each device's driver
(rig.devices.check_devices), the simulated sample's truth on the simulated rig, a new folder that is free, and
the disk space the points left will take (rig.acquisition.diskspace).
"""

from __future__ import annotations

from collections.abc import Callable, Collection
from dataclasses import replace
from pathlib import Path

from rig.acquisition.diskspace import estimate_dataset_bytes, space_problem
from rig.acquisition.execute import Prepared
from rig.config.campaign import Campaign, CampaignError, check_campaign_for_rig
from rig.config.rigfile import RigConfig
from rig.data.dataset_format import DatasetError
from rig.data.output_folder import require_new_output
from rig.devices import check_devices
from rig.planning.candidates import candidate_plan, logged_points
from rig.planning.plan import build_plan

#: What to do when a resumed folder's disk is too full.
RESUME_SPACE_REMEDY = "free some space, or move the folder to a disk with room and resume there"


def prepare_run(campaign: Campaign, rig: RigConfig, out: Path, *, campaign_file: str | Path | None = None,
                rig_file: str | Path = "<built-in rig>") -> Prepared:
    """A new run of `campaign` on `rig` into the new folder `out`, once the pre-flight passed (its ConfigFileError
    or DatasetError otherwise, naming `campaign_file` and `rig_file`); the manifest records `campaign_file`."""
    path = Path(campaign_file).resolve() if campaign_file else None      # the manifest's record works from anywhere
    return preflight(campaign, rig, out, campaign_file=campaign_file or f"campaign {campaign.name}",
                     rig_file=rig_file, campaign_path=path)


def preflight(campaign: Campaign, rig: RigConfig, out: Path, *, campaign_file: str | Path = "<campaign>",
              rig_file: str | Path = "<rig>", campaign_path: Path | None = None, done: Collection[str] | None = None,
              adaptive_log: Callable[[set[str]], list[dict]] | None = None) -> Prepared:
    """Check that `campaign` can run on `rig` into `out`: the run, or the first problem raised with its file's
    name (`campaign_file`, `rig_file`): a ConfigFileError for the inputs, a DatasetError for the folder or disk.

    The run holds the plan, the bytes the points left will add to the folder (rig.acquisition.diskspace, for the
    message of a full disk), `campaign_path` (the manifest's record of the campaign file) and a resumed adaptive
    campaign's logged batches. `done`: None for a new dataset folder (`out` must be absent or empty); for a resume,
    the point ids the folder already holds (rows and recovered written-ahead points), which the disk space leaves
    out. `adaptive_log(ids)`: a resumed adaptive campaign's `adaptive_batch` events among the candidate ids
    (rig.planning.candidates), whose points join the plan.
    """
    check_campaign_for_rig(campaign, rig, campaign_file)
    try:
        plan = build_plan(campaign, rig)
    except CampaignError as exc:            # a mandatory pair of an adaptive campaign the rig cannot measure
        raise CampaignError(f"{campaign_file}: {exc}") from None
    check_devices(rig, rig_file)
    if rig.simulated and campaign.sample.simulated_brdf is None:
        raise CampaignError(f"{campaign_file}: key 'sample.simulated_brdf' is required on the simulated rig "
                            "(the sample's true BRDF: model and params)")
    if not plan.points:
        raise CampaignError(f"{campaign_file}: no point of the campaign can be measured "
                            f"(skipped: {plan.skipped_by_reason()})")
    logged: list[dict] = []
    if adaptive_log is not None and campaign.sampling.mode == "adaptive":
        candidates = candidate_plan(campaign, rig)
        logged = adaptive_log({p.point_id for p in candidates.points})
        plan = replace(plan, points=plan.points + tuple(logged_points(candidates, logged)))
    if done is None:
        require_new_output(out)
        needed = estimate_dataset_bytes(len(plan.points), len(plan.skipped), rig, campaign.capture.save_images)
        problem = space_problem(out, needed)
    else:
        left = len({p.point_id for p in plan.points} - set(done))
        needed = estimate_dataset_bytes(left, 0, rig, campaign.capture.save_images)
        problem = space_problem(out, needed, RESUME_SPACE_REMEDY)
    if problem:
        raise DatasetError(problem)
    return Prepared(campaign, campaign_path, rig, plan, out, needed, logged_batches=logged)
