"""One way to run a campaign: `run_campaign` into a new dataset folder, `resume_campaign` to continue one.

Both pass the same pre-flight (rig.acquisition.preflight: campaign × rig, the devices' drivers, the plan, the disk
space) before any device is opened or anything written, and end in `Prepared.run` (rig.acquisition.execute). A
caller that says something between the checks and the connection (`rig run` prints what it is about to measure)
calls `prepare_run` (rig.acquisition.preflight) or `prepare_resume` (rig.acquisition.resume), then `.run(...)`.

Which rig to open, and an adaptive campaign's sampler, are parameters (`open_devices`, `sampler`), not imports:
connecting (rig.session.connect.open_campaign_rig) and the adaptive sampler (rig.session.adaptive_sampler) live in
rig.session, a layer above this one (pyproject.toml's import-linter layers), and a test may hand in a rig of its own
(one that cannot be reached, one whose peers it reaches into).
"""

from __future__ import annotations

from pathlib import Path

from rig.acquisition.execute import RigOpener, RunOutcome, SamplerFactory
from rig.acquisition.preflight import prepare_run
from rig.acquisition.resume import prepare_resume
from rig.config.campaign import Campaign
from rig.config.rigfile import RigConfig
from rig.core.values import ProgressCallback


def run_campaign(campaign: Campaign, rig: RigConfig, out: Path, open_devices: RigOpener, *,
                 campaign_file: str | Path | None = None, rig_file: str | Path = "<built-in rig>",
                 progress: ProgressCallback | None = None, handle_signals: bool = False,
                 sampler: SamplerFactory | None = None) -> RunOutcome:
    """Check, connect with `open_devices` (e.g. rig.session.connect.open_campaign_rig), measure `campaign` into the
    new folder `out`; how it ended. `handle_signals`: Ctrl+C and SIGTERM stop the run (main thread)."""
    return prepare_run(campaign, rig, out, campaign_file=campaign_file, rig_file=rig_file).run(
        open_devices, progress=progress, handle_signals=handle_signals, sampler=sampler)


def resume_campaign(folder: str | Path, open_devices: RigOpener, *, force: bool = False,
                    rig_file: str | Path | None = None, progress: ProgressCallback | None = None,
                    handle_signals: bool = False, sampler: SamplerFactory | None = None) -> RunOutcome:
    """Continue the interrupted or failed campaign in `folder` (rig.acquisition.resume: `force`, `rig_file`); the
    same pre-flight as `run_campaign`, then the same run."""
    return prepare_resume(folder, force=force, rig_file=rig_file).run(
        open_devices, progress=progress, handle_signals=handle_signals, sampler=sampler)
