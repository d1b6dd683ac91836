"""Soak benchmark: the paper campaign on the simulated rig under random faults (full form of
tests/session/test_soak.py). Prints the machine, the fault schedule, what the run survived (retries,
reconnects, pauses, restarts) and the comparison with a fault-free run of the same rig.

    python benchmarks/soak.py [--transient N] [--seed S]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))  # the soak's runs are a test helper (tests/soak_runs.py)

from rig.bench.error_vs_time import machine  # noqa: E402
from rig.config.campaign import load_campaign  # noqa: E402
from rig.config.rigfile import RigConfig  # noqa: E402
from rig.planning.plan import build_plan  # noqa: E402
from rig.simulators.faults import FaultSchedule  # noqa: E402
from soak_runs import compare, run_fault_free, run_with_faults  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaign", nargs="?", default=str(ROOT / "campaigns" / "spieringhs2023-rm1.yaml"))
    ap.add_argument("--transient", type=int, default=60, help="transient faults (retry level)")
    ap.add_argument("--silences", type=int, default=3, help="outages longer than the retries")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    path = Path(args.campaign)
    campaign, rig = load_campaign(path), RigConfig()
    n = len(build_plan(campaign, rig).points)
    schedule = FaultSchedule.random(n, seed=args.seed, transient=args.transient, silences=args.silences)
    print(f"machine : {machine()}")
    print(f"settings: {path.name}, {n} points, fault seed {args.seed}")
    print(f"faults  : {len(schedule.faults)} scheduled: "
          + ", ".join(f"{k} {v}" for k, v in sorted(schedule.counts().items())))
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        result = run_with_faults(campaign, path, rig, Path(tmp) / "faulty", schedule)
        faulty_s = time.perf_counter() - t0
        t0 = time.perf_counter()
        run_fault_free(campaign, path, rig, Path(tmp) / "reference")
        clean_s = time.perf_counter() - t0
        c = compare(Path(tmp) / "faulty", Path(tmp) / "reference")
    survived = {k: result.events.get(k, 0) for k in ("retry", "reconnect", "suspended", "resumed",
                                                     "points_discarded", "resume", "failed")}
    print(f"runs    : {[s for s, _ in result.attempts]} (restarts after persistent faults: {len(result.attempts) - 1})")
    print("survived: " + ", ".join(f"{k} {v}" for k, v in survived.items()))
    print(f"dataset : same point set {c.same_points}, duplicates {c.duplicates}, "
          f"{c.within_2u:.1%} within 2 combined u of the fault-free run, max z {c.max_z:.2f}")
    print(f"wall    : {faulty_s:.1f} s with faults vs {clean_s:.1f} s fault-free = {faulty_s / clean_s:.2f}× "
          "(driver timeouts are wall time)")
    return 0 if result.attempts[-1][0] == "complete" and c.same_points and c.duplicates == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
