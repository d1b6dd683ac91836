"""Soak runs: a campaign on the simulated rig under a random fault schedule, restarted with
`resume` after a persistent fault (as an operator would after resetting an alarm), and
compared point by point with a fault-free run of the same simulated rig."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.acquisition.engine import Runner
from rig.acquisition.execute import new_dataset
from rig.acquisition.outcome import RunEnding, ending_of
from rig.acquisition.resume import prepare_resume
from rig.acquisition.run import prepare_run, run_campaign
from rig.config.campaign import Campaign
from rig.config.rigfile import RigConfig
from rig.data.dataset_reader import load
from rig.session.connect import open_campaign_rig
from rig.simulators.faults import FaultInjector, FaultSchedule
from rig.simulators.rig import SimulatedRig


@dataclass
class SoakResult:
    attempts: list[tuple[str, str | None]]      # (status, error) of each run, the last one complete
    fired: int
    events: dict[str, int]                      # retries, reconnects, pauses… counted from events.jsonl


def run_with_faults(campaign: Campaign, campaign_path: Path, rig: RigConfig, out: Path,
                    schedule: FaultSchedule, max_restarts: int = 5) -> SoakResult:
    truth = campaign.sample.simulated_brdf
    if truth is None:
        raise ValueError(f"campaign {campaign.name!r}: a soak run needs the sample's simulated_brdf")
    prepared = prepare_run(campaign, rig, out, campaign_file=campaign_path)
    plan, writer = prepared.plan, new_dataset(prepared)
    injector = FaultInjector(schedule, {})
    done_rows: list[dict] = []
    attempts: list[tuple[str, str | None]] = []
    while True:
        sim = SimulatedRig(rig, truth.model, truth.params)
        devices = sim.start()           # stopped below, as `with SimulatedRig(...)` would
        try:
            injector.rebind(sim.peers)
            runner = Runner(campaign, plan, devices, writer, rig, progress=injector, done_rows=done_rows)
            try:
                ending = RunEnding(runner.run())
            except Exception as exc:      # a persistent fault: the runner already made the rig safe
                ending = ending_of(exc)
            attempts.append((ending.status, ending.message))
        finally:
            sim.stop()
        writer.close()
        if attempts[-1][0] == "complete" or len(attempts) > max_restarts:
            break
        resumed = prepare_resume(out)
        writer, done_rows = resumed.writer, resumed.done_rows
    counts: dict[str, int] = {}
    for line in (out / "events.jsonl").read_text().splitlines():
        kind = line.split('"event": "', 1)[1].split('"', 1)[0]
        counts[kind] = counts.get(kind, 0) + 1
    return SoakResult(attempts, len(injector.fired), counts)


def run_fault_free(campaign: Campaign, campaign_path: Path, rig: RigConfig, out: Path) -> str:
    return run_campaign(campaign, rig, out, open_campaign_rig, campaign_file=campaign_path).status


@dataclass(frozen=True)
class Comparison:
    same_points: bool
    duplicates: int
    within_2u: float          # fraction of points whose difference is within 2 combined u
    max_z: float


def compare(faulty: Path, reference: Path) -> Comparison:
    a, b = load(faulty), load(reference)
    ids_a, ids_b = a.point_id, b.point_id
    index_b = {pid: k for k, pid in enumerate(ids_b)}
    common = [pid for pid in ids_a if pid in index_b]
    ka = np.array([ids_a.index(pid) for pid in common])
    kb = np.array([index_b[pid] for pid in common])
    diff = a["brdf_per_sr"][ka] - b["brdf_per_sr"][kb]
    u = np.hypot(a["u_brdf_per_sr"][ka], b["u_brdf_per_sr"][kb])
    z = np.abs(diff) / u
    return Comparison(sorted(ids_a) == sorted(ids_b), len(ids_a) - len(set(ids_a)),
                      float(np.mean(z <= 2)), float(z.max()))
