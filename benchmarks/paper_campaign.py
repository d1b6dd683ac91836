"""Benchmark: the paper campaign (Spieringhs 2023 RM1, Table 1 × Table 2) on the simulated rig.

The simulated rig is the real drivers talking to in-process protocol peers over
loopback TCP (Modbus AZ drives, SCPI lamp supply) and a pseudo-terminal (P9710), plus
the in-process camera. Prints the machine and settings, the wall time of the
whole campaign, the per-point protocol overhead (round trips and milliseconds
spent in device exchanges), the time inside the simulated camera, and, as a
same-run baseline, a bare acquisition loop over the same points (move the axes
through the drivers, one ROI exposure, mean), so that the ratio pipeline/bare
does not depend on how fast this machine happens to be today.

    python benchmarks/paper_campaign.py [CAMPAIGN.yaml] [--repeat N]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.acquisition.engine import Runner  # noqa: E402
from rig.acquisition.execute import manifest_for  # noqa: E402
from rig.config.campaign import load_campaign  # noqa: E402
from rig.config.rigfile import RigConfig  # noqa: E402
from rig.core.values import Window  # noqa: E402
from rig.data.dataset import DatasetWriter  # noqa: E402
from rig.drivers.modbus_drive import ModbusDriveLink  # noqa: E402
from rig.drivers.transport import LineTransport  # noqa: E402
from rig.planning.plan import build_plan  # noqa: E402
from rig.session.bench import machine  # noqa: E402
from rig.simulators.rig import SimulatedRig  # noqa: E402


class Timed:
    """Proxy that adds the wall time of selected method calls to a shared counter."""

    def __init__(self, target, methods, counter):
        self._target, self._methods, self._counter = target, set(methods), counter

    def __getattr__(self, name):
        attr = getattr(self._target, name)
        if name not in self._methods:
            return attr

        def timed(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return attr(*args, **kwargs)
            finally:
                self._counter[name] = self._counter.get(name, 0.0) + time.perf_counter() - t0
        return timed


class ProtocolMeter:
    """Counts and times every device exchange: Modbus requests and ASCII queries/writes."""

    PATCHES = ((ModbusDriveLink, ("read", "write")), (LineTransport, ("query", "write_line")))

    def __init__(self):
        self.round_trips = 0
        self.seconds = 0.0
        self._saved = []

    def __enter__(self):
        for cls, names in self.PATCHES:
            for name in names:
                original = getattr(cls, name)
                self._saved.append((cls, name, original))
                setattr(cls, name, self._wrap(original))
        return self

    def _wrap(self, original):
        def counted(*args, **kwargs):
            t0 = time.perf_counter()
            try:
                return original(*args, **kwargs)
            finally:
                self.seconds += time.perf_counter() - t0
                self.round_trips += 1
        return counted

    def __exit__(self, *exc):
        for cls, name, original in self._saved:
            setattr(cls, name, original)


def run_campaign(campaign_path: Path) -> dict:
    campaign = load_campaign(campaign_path)
    rig = RigConfig()
    t0 = time.perf_counter()
    plan = build_plan(campaign, rig)
    t_plan = time.perf_counter() - t0
    truth = campaign.sample.simulated_brdf
    sim_time: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmp, SimulatedRig(rig, truth.model, truth.params) as sim, \
            ProtocolMeter() as wire:
        sim.devices.camera = Timed(sim.devices.camera, ("capture", "capture_dark"), sim_time)
        writer = DatasetWriter(Path(tmp) / "ds", manifest_for(campaign, campaign_path, rig))
        writer.write_skipped(plan.skipped)
        runner = Runner(campaign, plan, sim.devices, writer, rig)
        t0 = time.perf_counter()
        status = runner.run()
        wall = time.perf_counter() - t0
        writer.close()
    return {"status": status, "points": runner.measured, "skipped": len(plan.skipped), "wall_s": wall,
            "plan_s": t_plan, "sim_s": sum(sim_time.values()), "wire_s": wire.seconds,
            "round_trips": wire.round_trips, "rig_time_s": runner.rig_time(), "plan": plan, "campaign": campaign}


def bare_loop(plan, campaign) -> float:
    """Baseline: for every point move the axes through the drivers, take one ROI exposure, average it."""
    rig = RigConfig()
    truth = campaign.sample.simulated_brdf
    with SimulatedRig(rig, truth.model, truth.params) as sim:
        devices = sim.devices
        devices.lamp.set_output(True)
        devices.lamp.set_current(rig.lamp.current_a)
        cam = devices.camera
        roi = Window.centred(cam.sensor.width_px, cam.sensor.height_px, campaign.capture.roi_px,
                             campaign.capture.roi_px)
        axes = (*devices.stage.axes, *devices.arm.axes)
        t0 = time.perf_counter()
        for p in plan.points:
            for ax, target in zip(axes, p.motors_deg):
                ax.start_move(target)
            for ax in axes:
                ax.wait()
            float(np.mean(cam.capture(0.005, roi).pixels_dn))
        elapsed = time.perf_counter() - t0
        devices.lamp.set_output(False)
    return elapsed


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaign", nargs="?", default=str(ROOT / "campaigns" / "spieringhs2023-rm1.yaml"))
    ap.add_argument("--repeat", type=int, default=3, help="runs of each; the median is reported")
    args = ap.parse_args()
    path = Path(args.campaign)
    print(f"machine : {machine()}")
    print(f"settings: campaign {path.name}, simulated rig (default RigConfig), repeat {args.repeat}, median reported")
    runs = [run_campaign(path) for _ in range(args.repeat)]
    bares = [bare_loop(runs[0]["plan"], runs[0]["campaign"]) for _ in range(args.repeat)]
    med = {k: statistics.median(r[k] for r in runs) for k in ("wall_s", "sim_s", "wire_s", "plan_s")}
    n = runs[0]["points"]
    bare = statistics.median(bares)
    rest = med["wall_s"] - med["sim_s"] - med["wire_s"]
    print(f"status  : {runs[0]['status']}; {n} points measured, {runs[0]['skipped']} skipped; "
          f"rig time {runs[0]['rig_time_s'] / 3600:.2f} h simulated")
    print(f"wall    : {med['wall_s']:.2f} s for the campaign over the wire (target < 60 s); "
          f"planning {med['plan_s'] * 1e3:.0f} ms")
    print(f"protocol: {runs[0]['round_trips'] / n:.1f} round trips and {med['wire_s'] / n * 1e3:.2f} ms per point "
          f"(target < 10 ms), {med['wire_s'] / med['wall_s']:.0%} of the wall time")
    print(f"per pt  : {med['wall_s'] / n * 1e3:.2f} ms total = {med['wire_s'] / n * 1e3:.2f} ms device exchanges "
          f"+ {med['sim_s'] / n * 1e3:.2f} ms inside the simulated camera + {rest / n * 1e3:.2f} ms the rest "
          "(pipeline, dataset rows with fsync, peers' share of the CPU)")
    print(f"baseline: bare acquisition loop (drivers + one exposure) {bare / n * 1e3:.2f} ms per point; "
          f"full pipeline / bare = {med['wall_s'] / bare:.2f}×")
    return 0 if runs[0]["status"] == "complete" else 1


if __name__ == "__main__":
    sys.exit(main())
