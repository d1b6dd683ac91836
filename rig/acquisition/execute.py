"""Carry out a prepared run (rig.acquisition.run): connect, make or reopen the dataset folder, run the runner, and
say how it ended; Ctrl+C and SIGTERM become the runner's stop and abort requests."""

from __future__ import annotations

import os
import signal
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import AbstractContextManager, contextmanager, nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rig import __version__
from rig.acquisition.engine import Runner
from rig.acquisition.outcome import RunEnding, Status, ending_of, record_unstarted
from rig.acquisition.progress import stop_words
from rig.acquisition.stopping import AbortRequested
from rig.config.campaign import Campaign, campaign_sha256
from rig.config.rigfile import RigConfig
from rig.core.values import ProgressCallback
from rig.data.dataset_format import DatasetError
from rig.data.dataset_writer import DatasetWriter
from rig.drivers.interfaces import RigDevices
from rig.planning.estimate import WarmupEstimate
from rig.planning.points import Plan, PointSource


def manifest_for(campaign: Campaign, campaign_path: Path | None, rig: RigConfig) -> dict:
    """The manifest a new dataset starts with (docs/dataset.md: campaign, sample, rig, software, truth)."""
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
    status: Status
    measured: int
    rig_time_s: float
    wall_s: float
    out: Path
    error: str | None = None
    #: The lamp supply did not confirm the lamp off at the end (the lamp may still be on): why.
    lamp_problem: str | None = None
    #: Whether the dataset folder exists: a new one is made only once every device has answered.
    written: bool = True


class SignalRequests:
    """Ctrl+C and SIGTERM as flags for the runner, kept until there is one (the rig may still be connecting).

    Handlers only set flags and write one line to the terminal with os.write (no Python I/O,
    no device I/O, no exception): whatever the main thread is doing when a signal lands,
    the handler cannot tear it, and the runner's exit path runs to its end.
    """

    def __init__(self) -> None:
        self.runner: Runner | None = None
        self.stop: str | None = None
        self.abort: str | None = None

    def attach(self, runner: Runner) -> None:
        self.runner = runner
        self._forward()

    def _forward(self) -> None:
        if self.runner is not None:
            if self.stop:
                self.runner.request_stop(self.stop)
            if self.abort:
                self.runner.request_abort(self.abort)

    def on_sigint(self, signum: int, frame: object) -> None:
        """First Ctrl+C: finish the point, park, lamp off. Again: stop the axes now."""
        if self.stop is None:
            self.stop = "Ctrl+C"
            _say(stop_words(self.runner.eta.stage if self.runner is not None else None))
        elif self.abort is None:
            self.abort = "Ctrl+C again"
            _say("stopping the axes now, lamp off")
        self._forward()

    def on_sigterm(self, signum: int, frame: object) -> None:
        if self.abort is None:
            self.abort = "SIGTERM"
            _say("SIGTERM: stopping the axes now, lamp off")
        self._forward()


def _say(message: str) -> None:
    """One line on stderr from a signal handler: a raw write, never re-entering a Python stream."""
    try:
        os.write(2, f"\nrig: {message}\n".encode())
    except OSError:      # no terminal to tell: the flags are what matters
        pass


@contextmanager
def stop_on_signals(requests: SignalRequests) -> Iterator[None]:
    """SIGINT and SIGTERM go to `requests` for the duration of the block (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    saved = {sig: signal.signal(sig, handler) for sig, handler in ((signal.SIGINT, requests.on_sigint),
                                                                    (signal.SIGTERM, requests.on_sigterm))}
    try:
        yield
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


#: Opens the rig a campaign runs on (rig.session.connect.open_campaign_rig: the simulated or the real one).
RigOpener = Callable[[Campaign, RigConfig], AbstractContextManager[RigDevices]]
#: Where an adaptive campaign's further points come from, given its plan and a resumed run's logged batches
#: (rig.session.adaptive_sampler.sampler_for; None: the plan is all).
SamplerFactory = Callable[[Campaign, RigConfig, Plan, Sequence[dict]], PointSource | None]


@dataclass(frozen=True)
class Prepared:
    """A run that passed its pre-flight (rig.acquisition.run): what it measures, and where."""

    campaign: Campaign
    #: The campaign file, as the manifest records it (None: a campaign built in code).
    campaign_path: Path | None
    rig: RigConfig
    plan: Plan
    out: Path
    #: The dataset's estimated size, for the message of a full disk.
    space_needed_bytes: int | None = None
    #: A resume's reopened (and locked) folder; None: a new one is made once every device has answered.
    writer: DatasetWriter | None = None
    #: Rows already in the folder (a resume): their points are not measured again.
    done_rows: Sequence[dict] = ()
    #: A resumed adaptive campaign's logged batches, for its sampler.
    logged_batches: Sequence[dict] = ()
    #: The warm-up the run expects, for its first ETA (rig.session.warmup_estimate); None: the runner's default.
    warmup: WarmupEstimate | None = None

    def run(self, open_devices: RigOpener, *, progress: ProgressCallback | None = None, handle_signals: bool = False,
            sampler: SamplerFactory | None = None) -> RunOutcome:
        """Connect with `open_devices`, measure, and say how the run ended (`execute`); an opener that fails at
        once fails the run as one whose devices do not answer."""
        source = sampler(self.campaign, self.rig, self.plan, self.logged_batches) if sampler else None
        return execute(self, _opening(open_devices, self.campaign, self.rig), progress,
                       handle_signals=handle_signals, source=source)


@contextmanager
def _opening(open_devices: RigOpener, campaign: Campaign, rig: RigConfig) -> Iterator[RigDevices]:
    """`open_devices(campaign, rig)` called as the run enters it, within the run's handling of failures."""
    with open_devices(campaign, rig) as devices:
        yield devices


def new_dataset(prepared: Prepared) -> DatasetWriter:
    """The new dataset folder of `prepared`: its manifest and its skipped points (DatasetError if it cannot be
    made)."""
    writer = DatasetWriter(prepared.out, manifest_for(prepared.campaign, prepared.campaign_path, prepared.rig),
                           space_needed_bytes=prepared.space_needed_bytes)
    writer.write_skipped(prepared.plan.skipped)
    return writer


def execute(prepared: Prepared, devices: AbstractContextManager[RigDevices], progress: ProgressCallback | None = None,
            *, handle_signals: bool = False, source: PointSource | None = None) -> RunOutcome:
    """Measure `prepared.plan` into a new dataset folder, or into a resume's reopened one, leaving out its done rows.

    The new folder is made once `devices` has been entered, i.e. every device has answered: a rig
    that cannot be reached (a closed port, a served rig busy with another client) or a stop while
    connecting leaves nothing behind (`written` False), so the same command can simply be run again.
    DatasetError (nothing written) if the folder cannot be made.

    `source`: more points once the plan's are measured (an adaptive campaign: rig.session.adaptive_sampler).

    Device and other failures do not raise: they end as status `failed` with the
    completed points kept; the runner has already made the rig safe. How the run ended is
    decided by rig.acquisition.outcome.ending_of, as in the runner.
    """
    requests = SignalRequests()
    with stop_on_signals(requests) if handle_signals else nullcontext():
        return _execute(prepared, devices, progress, requests, source)


def _execute(prepared: Prepared, devices: AbstractContextManager[RigDevices], progress: ProgressCallback | None,
             requests: SignalRequests, source: PointSource | None) -> RunOutcome:
    """`execute` with the signals already routed to `requests`."""
    wall0 = time.perf_counter()
    runner = None
    writer = prepared.writer
    exit_report: dict[str, Any] = {}
    try:
        with devices as opened:
            exit_report = opened.exit_report
            if writer is None:
                if requests.stop or requests.abort:      # stopped while connecting: nothing was measured
                    raise AbortRequested(requests.abort or requests.stop)
                writer = new_dataset(prepared)
            runner = Runner(prepared.campaign, prepared.plan, opened, writer, prepared.rig, progress=progress,
                            done_rows=prepared.done_rows, source=source, warmup=prepared.warmup)
            requests.attach(runner)
            ending = RunEnding(runner.run())
    except (KeyboardInterrupt, Exception) as exc:   # KeyboardInterrupt: handle_signals=False, Python's Ctrl+C
        if writer is None and isinstance(exc, DatasetError):
            raise                       # the new folder could not be made (the rig is closed again)
        ending = ending_of(exc)
        if writer is not None and runner is None:   # a resumed folder whose rig never came up
            record_unstarted(writer, ending)
    finally:
        try:
            if writer is not None and "lamp_off_confirmed" in exit_report:     # the lamp as the supply confirmed it
                writer.update_manifest(lamp_at_exit={key: exit_report[key] for key in ("lamp_off_confirmed",
                                                                                       "lamp_problem")})
        finally:
            if writer is not None:
                writer.close()
    kept = runner.measured if runner else len(prepared.done_rows)   # a resume's points are kept even if the rig is not
    return RunOutcome(ending.status, kept, runner.rig_time() if runner else 0.0, time.perf_counter() - wall0,
                      prepared.out, ending.message, exit_report.get("lamp_problem"), written=writer is not None)
