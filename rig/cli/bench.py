"""`rig bench`: the command line of rig.bench.error_vs_time."""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import asdict
from pathlib import Path

import rig
from rig.bench import sampling as sampling_bench
from rig.bench import sampling_report as report
from rig.bench.distributed import Failure, study_client, workers_of
from rig.bench.draws import FAMILIES, draws
from rig.bench.error_vs_time import SETTINGS, format_table, machine, plot, run_settings
from rig.config.campaign import load_campaign
from rig.config.files import ConfigFileError
from rig.core.exits import EXIT_FAILED, EXIT_OK, fail

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
    """The sampling study on drawn samples, as dask tasks: per draw as it finishes, the distribution, PNG, JSON.
    Exit 1 when a task failed (each is listed with its draw and seed)."""
    path = Path(args.campaign)
    try:
        campaign = load_campaign(path)
    except ConfigFileError as exc:
        return fail(str(exc))
    unknown = [f for f in args.families if f not in FAMILIES]
    if unknown:
        return fail(f"unknown family {unknown[0]!r}; choose from {', '.join(FAMILIES)}")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.summarise:
        return _print_study(sampling_bench.load_results(out / "results.jsonl"), [], float("nan"), out)
    drawn = draws(args.seed, args.draws, args.first, tuple(args.families))
    recorded = (out / "results.jsonl").open("w")

    def record(results: list) -> None:
        recorded.write("".join(json.dumps(asdict(r)) + "\n" for r in results))
        recorded.flush()

    with recorded, study_client(args.scheduler, args.workers) as client:
        print(f"machine : {machine()}\ncampaign: {path.name} (the table; the adaptive runs' candidate domain); "
              f"simulated rig; draws {args.first}–{args.first + args.draws - 1} of seed {args.seed}; budgets "
              f"{', '.join(f'{f:g}' for f in args.budgets)} × the table's rig time; "
              f"{workers_of(client)} dask workers at {client.scheduler.address}", flush=True)
        for d in drawn:
            print(f"  {d.describe()}", flush=True)
        wall0 = time.perf_counter()
        results, failures = sampling_bench.study(client, campaign, drawn, args.budgets,
                                                 progress=lambda line: print(line, flush=True), record=record)
        wall = time.perf_counter() - wall0
    (out / "sampling.json").write_text(json.dumps(
        {"machine": machine(), "campaign": str(path), "seed": args.seed, "first": args.first, "wall_s": wall,
         "draws": [asdict(d) for d in drawn], "results": [asdict(r) for r in results],
         "failures": [asdict(f) for f in failures]}, indent=2))
    return _print_study(results, failures, wall, out)


def _print_study(results: list[sampling_bench.Result], failures: list[Failure], wall: float, out: Path) -> int:
    """Per draw, the distribution, the plot; exit 1 when a task failed."""
    for group in report.by_draw(results).values():
        print("\n" + report.format_draw(group) + "\n" + report.verdict(group))
    print("\n" + report.distribution(results, failures) + f"\nwall time of the study: {wall:.0f} s")
    if results:
        report.plot(results, out / "sampling.png")
    print(f"plot and figures in {out}")
    return EXIT_FAILED if failures else EXIT_OK


def add_subcommand(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `rig bench error-vs-time [CAMPAIGN] [--out DIR]`."""
    bench = subparsers.add_parser("bench", help="benchmarks on the simulated rig")
    which = bench.add_subparsers(dest="bench", required=True)
    evt = which.add_parser("error-vs-time", help="BRDF error against rig time for several capture settings")
    evt.add_argument("campaign", nargs="?", default=str(DEFAULT_CAMPAIGN),
                     help=f"campaign YAML whose captures are compared (default {DEFAULT_CAMPAIGN.name})")
    evt.add_argument("--out", default="runs/bench-error-vs-time", help="folder for the PNG and JSON")
    evt.set_defaults(func=cmd_error_vs_time)
    smp = which.add_parser("sampling", help="in-hull error against rig time per sampling strategy, on drawn samples "
                                            "(dask tasks)")
    smp.add_argument("campaign", nargs="?", default=str(DEFAULT_CAMPAIGN),
                     help=f"campaign YAML: the baseline table and the adaptive runs' candidates (default "
                          f"{DEFAULT_CAMPAIGN.name})")
    smp.add_argument("--draws", type=int, default=20, help="how many samples to draw (default 20)")
    smp.add_argument("--seed", type=int, default=1, help="the draws' seed (default 1); each draw also seeds its rig")
    smp.add_argument("--first", type=int, default=0, help="index of the first draw (default 0)")
    smp.add_argument("--families", nargs="+", default=list(FAMILIES), metavar="FAMILY",
                     help=f"families drawn in turn (default all: {', '.join(FAMILIES)})")
    smp.add_argument("--budgets", nargs="+", type=float, default=list(sampling_bench.BUDGET_FRACTIONS),
                     help="adaptive budgets as fractions of the table's rig time after warm-up")
    smp.add_argument("--workers", type=int, default=None,
                     help="dask workers of the LocalCluster (default one per core)")
    smp.add_argument("--scheduler", metavar="ADDRESS", default=None,
                     help="run on the dask scheduler at ADDRESS (host:port) instead of a LocalCluster")
    smp.add_argument("--out", default="runs/bench-sampling",
                     help="folder for the PNG, sampling.json and results.jsonl (each task's results as it finishes)")
    smp.add_argument("--summarise", action="store_true",
                     help="run nothing: print and plot the results.jsonl already in --out (a study cut short)")
    smp.set_defaults(func=cmd_sampling)
