"""Benchmark: estimated rig time of the paper campaigns in table order vs travel-time optimised order.

For each campaign (default: campaigns/spieringhs2023-rm*.yaml) prints the estimated rig
time (moves + the nominal capture per point that `rig plan` uses; lamp warm-up left
out, it is the same for both) in table order, in optimised order and in optimised
order with every point kept on the arm branch inverse kinematics chose, and in table
order with the best arm branches (to separate the gain of the order from that of the
branch choice), the ratios to table order, the points whose arm branch the optimisation switched, and the
planning wall time of each order (median of --repeat; table order is the same-run
baseline). The rig-time ratios are deterministic; only the wall times depend on the machine.

    python benchmarks/ordering.py [CAMPAIGN.yaml ...] [--rig RIG.yaml] [--repeat N]

Target: optimised ≤ 0.6 × table rig time on the paper campaign.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.bench.error_vs_time import machine  # noqa: E402
from rig.cli.main import NOMINAL_CAPTURE_S  # noqa: E402
from rig.config.campaign import load_campaign  # noqa: E402
from rig.config.rigfile import RigConfig, load_rig_config  # noqa: E402
from rig.planning.collisions import zones_of  # noqa: E402
from rig.planning.ordering import START_DEG, arm_branches, choose_branches, order_plan  # noqa: E402
from rig.planning.plan import build_plan, estimate_rig_time_s  # noqa: E402
from rig.planning.points import Plan  # noqa: E402


def timed_plans(campaign, rig, repeat: int) -> dict:
    """Plans in both orders and the median wall time of building each."""
    out = {}
    for ordering in ("table", "optimised"):
        walls = []
        for _ in range(repeat):
            t0 = time.perf_counter()
            plan = build_plan(campaign, rig, ordering=ordering)
            walls.append(time.perf_counter() - t0)
        out[ordering] = (plan, statistics.median(walls))
    return out


def with_best_branches(plan: Plan, rig: RigConfig) -> Plan:
    """The plan in its own order, each point on the arm branch that makes the whole path fastest."""
    candidates = arm_branches(np.array([p.motors_deg for p in plan.points]), rig.axes.limits(), zones_of(rig))
    chosen = candidates[np.arange(len(candidates)), choose_branches(rig.axes, np.asarray(START_DEG), candidates)]
    return replace(plan, points=tuple(replace(p, motors_deg=tuple(map(float, m))) for p, m in zip(plan.points, chosen)))


def report(path: Path, rig: RigConfig, repeat: int) -> float:
    """Print one campaign's comparison; return optimised / table rig time."""
    campaign = load_campaign(path)
    plans = timed_plans(campaign, rig, repeat)
    (table, t_wall), (opt, o_wall) = plans["table"], plans["optimised"]
    same_branch = order_plan(table, rig.axes, zones_of(rig), START_DEG, switch_branches=False)
    table_s, opt_s, same_s, best_s = (estimate_rig_time_s(p, rig.axes, NOMINAL_CAPTURE_S)
                                      for p in (table, opt, same_branch, with_best_branches(table, rig)))
    before = {p.point_id: p.motors_deg for p in table.points}
    switched = sum(p.motors_deg != before[p.point_id] for p in opt.points)
    print(f"{campaign.name}: {len(opt.points)} points in {len(opt.series)} series")
    print(f"  {'rig time':44s} {'h':>6s} {'× table':>8s}")
    for label, t in (("table order, inverse-kinematics branches", table_s),
                     ("optimised order, best branches (the plan)", opt_s),
                     ("optimised order, inverse-kinematics branches", same_s),
                     ("table order, best branches", best_s)):
        print(f"  {label:44s} {t / 3600:6.3f} {t / table_s:8.3f}")
    print(f"  branches: {switched} of {len(opt.points)} points moved to the other arm branch; the branch choice "
          f"saves {1 - opt_s / same_s:.1%} in optimised order, the order saves {1 - opt_s / best_s:.1%} "
          "with the best branches")
    print(f"  planning  table {t_wall * 1e3:.0f} ms, optimised {o_wall * 1e3:.0f} ms "
          f"({o_wall / t_wall:.1f} × table)")
    return opt_s / table_s


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaigns", nargs="*", type=Path,
                    default=sorted((ROOT / "campaigns").glob("spieringhs2023-rm*.yaml")))
    ap.add_argument("--rig", type=Path, help="rig file (default: the built-in simulated rig)")
    ap.add_argument("--repeat", type=int, default=5, help="plan builds per order; the median wall time is reported")
    args = ap.parse_args()
    rig = load_rig_config(args.rig) if args.rig else RigConfig()
    print(f"machine : {machine()}")
    print(f"settings: rig {args.rig or 'simulated (default RigConfig)'}, start {START_DEG}, "
          f"nominal capture {NOMINAL_CAPTURE_S * 1e3:.0f} ms per point, repeat {args.repeat}, median wall time")
    ratios = [report(path, rig, args.repeat) for path in args.campaigns]
    return 0 if all(r <= 0.6 for r in ratios) else 1


if __name__ == "__main__":
    sys.exit(main())
