"""`rig bench`: the command line of rig.bench.error_vs_time."""

from __future__ import annotations

import argparse
import json
from dataclasses import asdict
from pathlib import Path

import rig
from rig.bench import sampling as sampling_bench
from rig.bench.error_vs_time import SETTINGS, format_table, machine, plot, run_settings
from rig.config.campaign import load_campaign
from rig.config.files import ConfigFileError
from rig.core.exits import EXIT_OK, fail

#: The paper's road marking RM1, in the campaigns/ folder beside the rig package (the checkout).
DEFAULT_CAMPAIGN = Path(rig.__file__).resolve().parents[1] / "campaigns" / "spieringhs2023-rm1.yaml"


def cmd_error_vs_time(args: argparse.Namespace) -> int:
    """Run every capture setting, print the table, write the plot and the JSON."""
    path = Path(args.campaign)
    try:
        campaign = load_campaign(path)
    except ConfigFileError as exc:
        return fail(str(exc))
    results = run_settings(campaign, path, SETTINGS)
    print(format_table(results, path.name))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    plot(results, out / "error-vs-time.png", f"{campaign.name}: error against capture time")
    (out / "error-vs-time.json").write_text(json.dumps({"machine": machine(), "campaign": str(path),
                                                        "results": results}, indent=2))
    print(f"plot and figures in {out}")
    return EXIT_OK


def cmd_sampling(args: argparse.Namespace) -> int:
    """Every sampling strategy on every chosen sample: table, PNG, JSON."""
    path = Path(args.campaign)
    try:
        campaign = load_campaign(path)
    except ConfigFileError as exc:
        return fail(str(exc))
    unknown = [s for s in args.samples if s not in sampling_bench.SAMPLES]
    if unknown:
        return fail(f"unknown sample {unknown[0]!r}; choose from {', '.join(sampling_bench.SAMPLES)}")
    print(f"machine : {machine()}\ncampaign: {path.name} (the candidate domain of the adaptive runs); simulated rig, "
          f"seed {args.seed}; budgets {', '.join(f'{f:g}' for f in args.budgets)} × the baseline's rig time",
          flush=True)
    results, verdicts = [], []
    for sample in args.samples:
        mine = sampling_bench.bench_sample(campaign, sample, args.seed, args.budgets)
        results += mine
        verdicts.append(sampling_bench.verdict(mine))
        print(sampling_bench.format_results(mine) + "\n" + verdicts[-1], flush=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    sampling_bench.plot(results, out / "sampling.png")
    (out / "sampling.json").write_text(json.dumps({"machine": machine(), "campaign": str(path), "seed": args.seed,
                                                   "results": [asdict(r) for r in results], "verdicts": verdicts},
                                                  indent=2))
    if len(args.samples) > 1:                   # one sample's table was printed as it finished
        print("\n".join(["", sampling_bench.format_results(results), *verdicts]))
    print(f"plot and figures in {out}")
    return EXIT_OK


def add_subcommand(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `rig bench error-vs-time [CAMPAIGN] [--out DIR]`."""
    bench = subparsers.add_parser("bench", help="benchmarks on the simulated rig")
    which = bench.add_subparsers(dest="bench", required=True)
    evt = which.add_parser("error-vs-time", help="BRDF error against rig time for several capture settings")
    evt.add_argument("campaign", nargs="?", default=str(DEFAULT_CAMPAIGN),
                     help=f"campaign YAML whose captures are compared (default {DEFAULT_CAMPAIGN.name})")
    evt.add_argument("--out", default="runs/bench-error-vs-time", help="folder for the PNG and JSON")
    evt.set_defaults(func=cmd_error_vs_time)
    smp = which.add_parser("sampling", help="validation error of the dataset against rig time, per sampling strategy")
    smp.add_argument("campaign", nargs="?", default=str(DEFAULT_CAMPAIGN),
                     help=f"campaign YAML: the baseline table and the adaptive runs' candidates (default "
                          f"{DEFAULT_CAMPAIGN.name})")
    smp.add_argument("--samples", nargs="+", default=list(sampling_bench.SAMPLES), metavar="SAMPLE",
                     help=f"simulated samples (default all: {', '.join(sampling_bench.SAMPLES)})")
    smp.add_argument("--budgets", nargs="+", type=float, default=list(sampling_bench.BUDGET_FRACTIONS),
                     help="adaptive budgets as fractions of the baseline's rig time after warm-up")
    smp.add_argument("--seed", type=int, default=1, help="simulated rig seed (the same for every strategy)")
    smp.add_argument("--out", default="runs/bench-sampling", help="folder for the PNG and JSON")
    smp.set_defaults(func=cmd_sampling)
