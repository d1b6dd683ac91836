"""Benchmark: the paper campaign (Spieringhs 2023 RM1, Table 1 × Table 2) on the simulated rig.

Prints the machine and settings, the wall time of the whole campaign, the
per-point software overhead (wall time not spent inside the simulated devices)
and, as a same-run baseline, a bare acquisition loop over the same points (set
the axes, one ROI exposure, mean) so the ratio pipeline/bare does not depend on
how fast this machine happens to be today.

    python benchmarks/paper_campaign.py [CAMPAIGN.yaml] [--repeat N]
"""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from drivers.interfaces import Window  # noqa: E402
from rig.campaign import load_campaign  # noqa: E402
from rig.cli import manifest_for  # noqa: E402
from rig.dataset import DatasetWriter  # noqa: E402
from rig.plan import build_plan  # noqa: E402
from rig.rigconfig import RigConfig  # noqa: E402
from rig.runner import Runner  # noqa: E402
from simulators.rig import build_simulated_rig  # noqa: E402


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


def machine() -> str:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (f"{platform.node()} | {cpu} | {os.cpu_count()} cores | Python {platform.python_version()} | "
            f"numpy {np.__version__} | {platform.platform()}")


def run_campaign(campaign_path: Path) -> dict:
    campaign = load_campaign(campaign_path)
    rig = RigConfig()
    t0 = time.perf_counter()
    plan = build_plan(campaign, rig)
    t_plan = time.perf_counter() - t0
    truth = campaign.sample.simulated_brdf
    devices, _ = build_simulated_rig(rig, truth.model, truth.params)
    sim_time: dict[str, float] = {}
    devices.camera = Timed(devices.camera, ("capture", "capture_dark"), sim_time)
    with tempfile.TemporaryDirectory() as tmp:
        writer = DatasetWriter(Path(tmp) / "ds", manifest_for(campaign, campaign_path, rig))
        writer.write_skipped(plan.skipped)
        writer_time: dict[str, float] = {}
        timed_writer = Timed(writer, ("append_row",), writer_time)
        runner = Runner(campaign, plan, devices, timed_writer, rig)
        t0 = time.perf_counter()
        status = runner.run()
        wall = time.perf_counter() - t0
        writer.close()
    return {"status": status, "points": runner.measured, "skipped": len(plan.skipped), "wall_s": wall,
            "plan_s": t_plan, "sim_s": sum(sim_time.values()), "write_s": sum(writer_time.values()),
            "rig_time_s": runner.rig_time(), "plan": plan, "campaign": campaign}


def bare_loop(plan, campaign) -> float:
    """Baseline: for every point set the axes, take one ROI exposure and average it."""
    rig = RigConfig()
    truth = campaign.sample.simulated_brdf
    devices, _ = build_simulated_rig(rig, truth.model, truth.params)
    devices.lamp.set_output(True)
    devices.lamp.set_current(rig.lamp.current_a)
    cam = devices.camera
    roi = Window.centred(cam.sensor.width_px, cam.sensor.height_px, campaign.capture.roi_px, campaign.capture.roi_px)
    axes = (*devices.stage.axes, *devices.arm.axes)
    t0 = time.perf_counter()
    for p in plan.points:
        for ax, target in zip(axes, p.motors_deg):
            ax.start_move(target)
        for ax in axes:
            ax.wait()
        float(np.mean(cam.capture(0.005, roi).pixels_dn))
    return time.perf_counter() - t0


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
    med = {k: statistics.median(r[k] for r in runs) for k in ("wall_s", "sim_s", "write_s", "plan_s")}
    n = runs[0]["points"]
    bare = statistics.median(bares)
    overhead = med["wall_s"] - med["sim_s"]
    print(f"status  : {runs[0]['status']}; {n} points measured, {runs[0]['skipped']} skipped; "
          f"rig time {runs[0]['rig_time_s'] / 3600:.2f} h simulated")
    print(f"wall    : {med['wall_s']:.2f} s for the campaign (target < 60 s); planning {med['plan_s'] * 1e3:.0f} ms")
    print(f"per pt  : {med['wall_s'] / n * 1e3:.2f} ms total = {med['sim_s'] / n * 1e3:.2f} ms inside the simulated "
          f"camera + {overhead / n * 1e3:.2f} ms software overhead (of which {med['write_s'] / n * 1e3:.2f} ms "
          "appending + fsync of the row)")
    print(f"baseline: bare acquisition loop {bare / n * 1e3:.2f} ms per point; "
          f"full pipeline / bare = {med['wall_s'] / bare:.2f}×")
    return 0 if runs[0]["status"] == "complete" else 1


if __name__ == "__main__":
    sys.exit(main())
