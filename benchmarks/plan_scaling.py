"""Benchmark: planning time against the number of incidence series (defect 9: 10,000 series took 339 s).

Generated campaigns with N incidence series (θi from 0.5° to 85° on √(N/10) planes of
incidence) of eight views each (a ring of two circles around the mirror direction), planned
on the simulated rig in table order and in optimised order (`rig plan` builds both). For each
N it prints the points, the wall time of each order, the CPU time per point (this process only,
so that other work on a shared machine counts less) and its ratio to the smallest N of the same
run (1.0 is linear scaling), and the optimised/table rig time (moves only) so that the speed is
not bought with a worse order. The ratios, not the seconds, are the result; the seconds depend
on the machine.

    python benchmarks/plan_scaling.py [--series 100 1000 10000]

Target: CPU time per point at the largest N ≤ 2 × that at the smallest.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.bench.error_vs_time import machine  # noqa: E402
from rig.config.campaign import Campaign, parse_campaign  # noqa: E402
from rig.config.rigfile import RigConfig  # noqa: E402
from rig.planning.ordering import BLOCK_NODES  # noqa: E402
from rig.planning.plan import build_plan, estimate_rig_time_s  # noqa: E402

#: Largest N's CPU time per point over the smallest's that still counts as linear.
TARGET_RATIO = 2.0
VIEWING = [{"centred_on": "mirror", "theta": [3.3, 10.7], "phi": [0, 90, 180, 270]}]


def campaign(n_series: int) -> Campaign:
    """n_series distinct incidences: θi from 0.5° to 85° on about √(n/10) planes of incidence."""
    planes = max(1, round(math.sqrt(n_series / 10)))
    per_plane = math.ceil(n_series / planes)
    thetas = np.linspace(0.5, 85.0, per_plane).round(9).tolist()
    incidence = [{"phi": round(360.0 * k / planes, 9), "theta": thetas} for k in range(planes)]
    return parse_campaign({"name": f"scaling-{n_series}", "sample": {"id": "generated"},
                           "incidence": incidence, "viewing": VIEWING})


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--series", type=int, nargs="+", default=[100, 1000, 10000],
                    help="numbers of incidence series; the first is the baseline")
    args = ap.parse_args()
    rig = RigConfig()
    print(f"machine : {machine()}")
    print(f"settings: simulated rig (default RigConfig), 8 views per series around the mirror direction, "
          f"ordering block {BLOCK_NODES} nodes, one build per order")
    print(f"{'series':>7s} {'points':>7s} {'table s':>8s} {'optim. s':>8s} {'CPU ms/point':>12s} "
          f"{'× base':>7s} {'opt/table rig time':>18s}")
    base = None
    for n in args.series:
        c = campaign(n)
        cpu0, t0 = time.process_time(), time.perf_counter()
        table = build_plan(c, rig, ordering="table")
        t1 = time.perf_counter()
        opt = build_plan(c, rig, ordering="optimised")
        t2, cpu2 = time.perf_counter(), time.process_time()
        per_point = (cpu2 - cpu0) / max(1, opt.n_planned)
        base = base or per_point
        gain = estimate_rig_time_s(opt, rig.axes, 0.0) / estimate_rig_time_s(table, rig.axes, 0.0)
        print(f"{len(opt.series):7d} {len(opt.points):7d} {t1 - t0:8.2f} {t2 - t1:8.2f} {per_point * 1e3:12.3f} "
              f"{per_point / base:7.2f} {gain:18.3f}", flush=True)
    ratio = per_point / base
    print(f"CPU time per point, largest / smallest: {ratio:.2f} (target ≤ {TARGET_RATIO})")
    return 0 if ratio <= TARGET_RATIO else 1


if __name__ == "__main__":
    sys.exit(main())
