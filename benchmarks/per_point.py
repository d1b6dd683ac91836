"""Benchmark: where the wall time of one point goes on the simulated rig, against a bare acquisition loop.

Runs the paper campaign (Spieringhs 2023 RM1; its first --points points, or all of them with --full)
in-process on the built-in simulated rig (real drivers, protocol peers on loopback and a pty, the
in-process camera) and prints, per measured point:

- wall time of the full pipeline (`Runner.run` from its first point on: suspender checks, E⊥ readings, moves,
  read-back, HDR capture and reduce, rows, fsync'ed dataset writes; the lamp's warm-up before it, connecting and
  rig time spent warming up, is printed apart);
- round trips per device from the first point on (the warm-up's are printed apart): one per request put
  on the wire (a Modbus FC 3/FC 16 request through `ModbusDriveLink.read`/`write`; an ASCII line through
  `LineTransport.write_line`, which every query and every setting sends once), counted by monkeypatching
  those two classes here only, with the wall time spent inside them;
- wall time inside the simulated camera (`capture`, `capture_dark`);
- the process's CPU time (every peer runs in this process), steadier than wall time on a busy machine;
- the bare acquisition loop, measured in the same run on a fresh simulated rig: lamp on, then for
  every point of the same plan start the stage and the arm toward it, wait for both, read the four
  encoders back and acquire the point's frames exactly as the pipeline does (`capturer.acquire()` with
  the run's capturer, of the campaign's capture settings and with its dark-frame cache: probe, bracket,
  frames and darks through the same drivers), and nothing else: no HDR reduce of the frames, no suspender checks, no E⊥
  readings, no rows, no dataset. What the pipeline adds on top of it is its overhead.

    python benchmarks/per_point.py [CAMPAIGN.yaml] [--points N | --full] [--repeat N]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.acquisition.capturer import capturer_for  # noqa: E402
from rig.acquisition.engine import Runner  # noqa: E402
from rig.acquisition.execute import manifest_for  # noqa: E402
from rig.acquisition.moves import Mover  # noqa: E402
from rig.bench.error_vs_time import machine  # noqa: E402
from rig.config.campaign import Campaign, load_campaign  # noqa: E402
from rig.config.rigfile import RigConfig  # noqa: E402
from rig.data.dataset_writer import DatasetWriter  # noqa: E402
from rig.drivers.modbus_drive import ModbusDriveLink  # noqa: E402
from rig.drivers.transport import LineTransport  # noqa: E402
from rig.planning.plan import build_plan  # noqa: E402
from rig.planning.points import Plan  # noqa: E402
from rig.simulators.rig import SimulatedRig  # noqa: E402

PAPER = ROOT / "campaigns" / "spieringhs2023-rm1.yaml"


@dataclass
class Meter:
    """Round trips per device and wall time inside the wire exchanges and the camera."""

    trips: Counter[str] = field(default_factory=Counter)
    wire_s: float = 0.0
    camera_s: float = 0.0
    _depth: int = 0

    def timed(self, original: Callable[..., Any], device_of: Callable[[Any], str] | None,
              slot: str) -> Callable[..., Any]:
        """`original` wrapped: counted as a round trip of `device_of(self)` (if given), its outermost calls
        timed into `slot` (a nested call, a query's own write_line, is not timed twice)."""
        meter = self

        def wrapped(obj: Any, *args: Any, **kwargs: Any) -> Any:
            if device_of is not None:
                meter.trips[device_of(obj)] += 1
            meter._depth += 1
            t0 = time.perf_counter()
            try:
                return original(obj, *args, **kwargs)
            finally:
                meter._depth -= 1
                if meter._depth == 0:
                    setattr(meter, slot, getattr(meter, slot) + time.perf_counter() - t0)
        return wrapped


@contextmanager
def metered(camera_class: type) -> Iterator[Meter]:
    """Count and time every exchange of the Modbus links and line transports, and the camera's captures."""
    meter = Meter()
    patches: list[tuple[type, str, Callable[[Any], str] | None, str]] = [
        (ModbusDriveLink, "read", lambda link: link.name, "wire_s"),
        (ModbusDriveLink, "write", lambda link: link.name, "wire_s"),
        (LineTransport, "write_line", lambda line: line.device, "wire_s"),
        (LineTransport, "query", None, "wire_s"),
        (camera_class, "capture", None, "camera_s"),
        (camera_class, "capture_dark", None, "camera_s")]
    saved = [(cls, name, cls.__dict__[name]) for cls, name, _, _ in patches]
    try:
        for cls, name, device_of, slot in patches:
            setattr(cls, name, meter.timed(cls.__dict__[name], device_of, slot))
        yield meter
    finally:
        for cls, name, original in saved:
            setattr(cls, name, original)


@dataclass(frozen=True)
class Run:
    wall_s: float
    points: int
    trips: Counter[str]
    wire_s: float
    camera_s: float
    cpu_s: float
    status: str = ""
    warm_up_trips: Counter[str] = field(default_factory=Counter)
    warm_up_s: float = 0.0


def pipeline(campaign: Campaign, campaign_path: Path, plan: Plan, rig: RigConfig) -> Run:
    """The full pipeline: Runner.run on the simulated rig, writing a dataset to a temporary folder."""
    truth = campaign.sample.simulated_brdf
    assert truth is not None, "the campaign names no simulated sample"
    with tempfile.TemporaryDirectory() as tmp, SimulatedRig(rig, truth.model, truth.params) as sim:
        assert sim.devices is not None
        with metered(type(sim.devices.camera)) as meter:
            writer = DatasetWriter(Path(tmp) / "ds", manifest_for(campaign, campaign_path, rig))
            writer.write_skipped(plan.skipped)
            runner = Runner(campaign, plan, sim.devices, writer, rig)
            before = Counter(meter.trips)           # connecting ...
            warm_up: Counter[str] = Counter()        # ... and the lamp's warm-up are not per point
            measure_all = runner._measure_all
            t0, cpu0 = time.perf_counter(), time.process_time()
            start = {"wall": t0, "cpu": cpu0, "wire": 0.0, "camera": 0.0}

            def measure_after_warm_up() -> None:
                warm_up.update(meter.trips - before)
                start.update(wall=time.perf_counter(), cpu=time.process_time(), wire=meter.wire_s,
                             camera=meter.camera_s)
                measure_all()
            runner._measure_all = measure_after_warm_up      # type: ignore[method-assign]
            status = runner.run()
            wall, cpu = time.perf_counter() - start["wall"], time.process_time() - start["cpu"]
            writer.close()
    return Run(wall, runner.measured, meter.trips - before - warm_up, meter.wire_s - start["wire"],
               meter.camera_s - start["camera"], cpu, status, warm_up, start["wall"] - t0)


def bare_loop(campaign: Campaign, plan: Plan, rig: RigConfig) -> Run:
    """The bare acquisition loop of the module docstring, on a fresh simulated rig."""
    truth = campaign.sample.simulated_brdf
    assert truth is not None, "the campaign names no simulated sample"
    settings = campaign.capture.settings()
    with SimulatedRig(rig, truth.model, truth.params) as sim:
        devices = sim.devices
        assert devices is not None
        devices.lamp.set_output(True)
        devices.lamp.set_current(rig.lamp.current_a)
        capturer = capturer_for(devices.camera, settings, devices.clock)
        mover = Mover(devices, rig)
        with metered(type(devices.camera)) as meter:
            t0, cpu0 = time.perf_counter(), time.process_time()
            for point in plan.points:
                mover.move(point.motors_deg)
                mover.read_back()
                capturer.acquire()
            wall, cpu = time.perf_counter() - t0, time.process_time() - cpu0
        devices.lamp.set_output(False)
    return Run(wall, len(plan.points), meter.trips, meter.wire_s, meter.camera_s, cpu)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaign", nargs="?", default=str(PAPER))
    ap.add_argument("--points", type=int, default=300, help="the plan's first N points (default 300)")
    ap.add_argument("--full", action="store_true", help="all points of the plan")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each, alternated; the fastest of each is reported")
    args = ap.parse_args()
    path = Path(args.campaign)
    campaign, rig = load_campaign(path), RigConfig()
    plan = build_plan(campaign, rig)
    if not args.full:
        plan = replace(plan, points=plan.points[:args.points])
    print(f"machine : {machine()}")
    print(f"settings: {path.name}, {len(plan.points)} points{' (--full)' if args.full else ''}, simulated rig "
          f"(default RigConfig), repeat {args.repeat} alternated, best of each reported")
    runs: list[Run] = []
    bares: list[Run] = []
    for _ in range(args.repeat):          # alternated: a busy spell of the machine slows both alike
        runs.append(pipeline(campaign, path, plan, rig))
        bares.append(bare_loop(campaign, plan, rig))
    run, bare = min(runs, key=lambda r: r.wall_s), min(bares, key=lambda r: r.wall_s)
    n = run.points
    ms = 1e3 / n
    print(f"status  : {run.status}; {n} points measured")
    print(f"per pt  : {run.wall_s * ms:.2f} ms = {run.wire_s * ms:.2f} ms device exchanges "
          f"+ {run.camera_s * ms:.2f} ms simulated camera + {(run.wall_s - run.wire_s - run.camera_s) * ms:.2f} ms "
          "the rest (merge, rows, fsync'ed writes, peers' share of the CPU)")
    for name, r in (("pipeline", run), ("bare", bare)):
        per = ", ".join(f"{d} {c / r.points:.2f}" for d, c in sorted(r.trips.items()))
        print(f"trips   : {name}: {sum(r.trips.values()) / r.points:.2f} round trips per point ({per})")
    print(f"warm-up : {run.warm_up_s:.2f} s wall and {sum(run.warm_up_trips.values())} round trips before the first "
          f"point ({', '.join(f'{d} {c}' for d, c in sorted(run.warm_up_trips.items()))}), not counted per point")
    print(f"bare    : {bare.wall_s / bare.points * 1e3:.2f} ms per point = {bare.wire_s / bare.points * 1e3:.2f} ms "
          f"device exchanges + {bare.camera_s / bare.points * 1e3:.2f} ms simulated camera + rest")
    print(f"ratio   : full pipeline / bare acquisition loop = {run.wall_s / n / (bare.wall_s / bare.points):.2f}× "
          f"(best walls {run.wall_s:.2f} s / {bare.wall_s:.2f} s; of the medians "
          f"{statistics.median(r.wall_s for r in runs) / statistics.median(r.wall_s for r in bares):.2f}×)")
    print(f"cpu     : {run.cpu_s * ms:.2f} ms per point of this process's CPU (driver, peers and camera alike) against "
          f"{bare.cpu_s / bare.points * 1e3:.2f} ms bare: {run.cpu_s / n / (bare.cpu_s / bare.points):.2f}× "
          "(steadier than wall time on a busy machine; misses the fsync waits)")
    return 0 if all(r.status == "complete" for r in runs) else 1


if __name__ == "__main__":
    sys.exit(main())
