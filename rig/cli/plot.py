"""`rig plot`: the command line of rig.analysis.plots."""

from __future__ import annotations

import argparse
import sys

from rig.analysis.plots import plot_dataset
from rig.analysis.result_files import read_fit
from rig.core.exits import EXIT_OK, fail
from rig.core.interrupts import interruptible
from rig.data.dataset_format import DatasetError


@interruptible
def cmd_plot(args: argparse.Namespace) -> int:
    """Plot, say how many figures on stderr; bad input and unwritable output are exit code 2."""
    try:
        fit = read_fit(args.fit) if args.fit else None
        paths = plot_dataset(args.dataset, args.out, fit)
    except (DatasetError, ValueError, KeyError) as exc:
        return fail(str(exc).strip('"'))
    except OSError as exc:
        return fail(f"{exc.filename}: {exc.strerror}")
    print(f"{len(paths)} figures in {args.out}", file=sys.stderr)
    return EXIT_OK


def add_subcommand(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `rig plot DATASET [--fit FIT.json] --out DIR`."""
    p = subparsers.add_parser("plot", help="PNG figures per incidence series: the plane of incidence and the 3D lobe "
                                           "(plane_/lobe_sNN_tiXX_piYYY.png: series, θi, φi) and, with --fit, "
                                           "fit_residuals.png")
    p.add_argument("dataset", metavar="DATASET", help="dataset folder")
    p.add_argument("--fit", metavar="FIT.json",
                   help="a fit written by `rig fit DATASET --model NAME --json`: its curve, surface and residuals "
                        "are drawn in")
    p.add_argument("--out", required=True, help="new folder for the PNG files (must not exist or be empty)")
    p.set_defaults(func=cmd_plot)
