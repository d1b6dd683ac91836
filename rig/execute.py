"""Run one campaign end to end: dataset folder, rig, runner; used by `rig run` and the benches."""

from __future__ import annotations

import signal
import threading
import time
from contextlib import contextmanager, nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Sequence

from rig import __version__
from rig.campaign import Campaign, campaign_sha256
from rig.connect import open_rig
from rig.dataset import DatasetWriter
from rig.plan import Plan
from rig.rigconfig import RigConfig
from rig.runner import ProgressCallback, Runner


def manifest_for(campaign: Campaign, campaign_path: Path | None, rig: RigConfig) -> dict:
    """The manifest a new dataset starts with (dataset.md: campaign, sample, rig, software, truth)."""
    manifest = {
        "campaign": {"name": campaign.name, "file": str(campaign_path) if campaign_path else None,
                     "sha256": campaign_sha256(campaign_path) if campaign_path else None,
                     "content": campaign.model_dump(mode="json")},
        "sample": campaign.sample.model_dump(mode="json", exclude={"simulated_brdf"}),
        "rig": {"name": rig.name, "simulated": rig.simulated, "config": rig.model_dump(mode="json")},
        "software": {"name": "rig", "version": __version__},
        "counts": {},
    }
    if rig.simulated and campaign.sample.simulated_brdf is not None:
        manifest["simulated_brdf"] = campaign.sample.simulated_brdf.model_dump(mode="json")
    return manifest


@dataclass(frozen=True)
class RunOutcome:
    status: str                 # complete | interrupted | failed
    measured: int
    rig_time_s: float
    wall_s: float
    out: Path
    error: str | None = None


@contextmanager
def stop_on_signals(runner: Runner) -> Iterator[None]:
    """First Ctrl+C: finish the point, park, lamp off. Second Ctrl+C or SIGTERM: stop the axes now."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def on_sigint(signum, frame):
        if runner.stop_requested:
            raise KeyboardInterrupt
        runner.request_stop("Ctrl+C (again to stop the axes now)")

    def on_sigterm(signum, frame):
        raise KeyboardInterrupt

    saved = {sig: signal.signal(sig, handler) for sig, handler in ((signal.SIGINT, on_sigint),
                                                                    (signal.SIGTERM, on_sigterm))}
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


def execute(campaign: Campaign, campaign_path: Path | None, rig: RigConfig, plan: Plan, out: Path,
            progress: ProgressCallback | None = None, *, writer: DatasetWriter | None = None,
            done_rows: Sequence[dict] = (), handle_signals: bool = False) -> RunOutcome:
    """Measure `plan` into a new dataset folder `out` (DatasetError if it cannot be created),
    or into `writer`'s reopened folder, leaving out `done_rows` (a resume).

    Device and other failures do not raise: they end as status `failed` with the
    completed points kept; the runner has already made the rig safe.
    """
    if writer is None:
        writer = DatasetWriter(out, manifest_for(campaign, campaign_path, rig))
        writer.write_skipped(plan.skipped)
    truth = campaign.sample.simulated_brdf
    wall0 = time.perf_counter()
    runner = None
    try:
        with open_rig(rig, truth.model if truth else None, truth.params if truth else None) as devices:
            runner = Runner(campaign, plan, devices, writer, rig, progress=progress, done_rows=done_rows)
            with stop_on_signals(runner) if handle_signals else nullcontext():
                status = runner.run()
        error = None
    except KeyboardInterrupt:    # a second Ctrl+C while parking; the runner made the rig safe
        status, error = "interrupted", None
    except Exception as exc:
        status, error = "failed", f"{exc}"
        if runner is None:       # the rig never came up, so no runner recorded the failure
            writer.event("failed", error=error)
            writer.update_manifest(status="failed", error=error)
    finally:
        writer.close()
    return RunOutcome(status, runner.measured if runner else 0, runner.rig_time() if runner else 0.0,
                      time.perf_counter() - wall0, out, error)
