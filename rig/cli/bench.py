"""`rig bench`: the command line of rig.session.bench."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import rig
from rig.config.campaign import load_campaign
from rig.config.files import ConfigFileError
from rig.core.exits import EXIT_OK, fail
from rig.session.bench import SETTINGS, format_table, machine, plot, run_settings

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


def add_subcommand(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `rig bench error-vs-time [CAMPAIGN] [--out DIR]`."""
    bench = subparsers.add_parser("bench", help="benchmarks on the simulated rig")
    which = bench.add_subparsers(dest="bench", required=True)
    evt = which.add_parser("error-vs-time", help="BRDF error against rig time for several capture settings")
    evt.add_argument("campaign", nargs="?", default=str(DEFAULT_CAMPAIGN))
    evt.add_argument("--out", default="runs/bench-error-vs-time", help="folder for the PNG and JSON")
    evt.set_defaults(func=cmd_error_vs_time)
