"""Benchmark: how much faster `rig bench sampling`'s study runs on 2 dask workers than on 1 (issue 33).

Runs the same study (the same draws, strategies and budgets) on a LocalCluster of 1 worker, then of 2 (one
single-threaded process each), and prints the wall time of each (the study only: the cluster is started before
the clock starts), their ratio, the machine and its load average before and after (the machine may be shared:
a ratio measured under load says what this machine gave, not what two free cores give).

    python benchmarks/sampling_speedup.py [CAMPAIGN] [--draws 6] [--seed 3] [--budgets 0.25 0.5]
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.bench.distributed import study_client  # noqa: E402
from rig.bench.draws import draws  # noqa: E402
from rig.bench.error_vs_time import machine  # noqa: E402
from rig.bench.sampling import study  # noqa: E402
from rig.config.campaign import load_campaign  # noqa: E402


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("campaign", nargs="?", default=str(ROOT / "tests" / "campaigns" / "sampling-tiny.yaml"))
    parser.add_argument("--draws", type=int, default=6)
    parser.add_argument("--seed", type=int, default=3)
    parser.add_argument("--budgets", nargs="+", type=float, default=[0.25, 0.5])
    args = parser.parse_args()
    campaign = load_campaign(Path(args.campaign))
    drawn = draws(args.seed, args.draws)
    print(machine())
    print(f"campaign {Path(args.campaign).name}; {args.draws} draws of seed {args.seed}; budgets {args.budgets}")
    walls = {}
    for workers in (1, 2):
        load_before = os.getloadavg()[0]
        with study_client(workers=workers) as client:
            start = time.perf_counter()
            results, failures = study(client, campaign, drawn, args.budgets)
            walls[workers] = time.perf_counter() - start
        print(f"{workers} worker(s): {walls[workers]:.1f} s wall, {len(results)} results, {len(failures)} failed; "
              f"load average {load_before:.1f} before, {os.getloadavg()[0]:.1f} after", flush=True)
    print(f"2 workers / 1 worker: {walls[2] / walls[1]:.2f} (the issue's bar: ≤ 0.6)")


if __name__ == "__main__":
    main()
