"""`rig report DATASET --out report.html [--fit FIT.json] [--road road.json]`: the measurement report
(rig.report), one HTML file with everything in it."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from rig.analysis.result_files import read_fit, read_road
from rig.core.exits import EXIT_OK, fail
from rig.core.interrupts import interruptible
from rig.data.dataset_format import DatasetError
from rig.data.dataset_reader import load
from rig.data.output_folder import new_file
from rig.report import report_html


@interruptible
def cmd_report(args: argparse.Namespace) -> int:
    """Write the report; refuse an existing --out (as rig export does); bad input is exit code 2."""
    out = Path(args.out)
    if out.exists():
        return fail(f"{out} already exists; choose another --out (nothing was overwritten)")
    try:
        ds = load(Path(args.dataset))
        fit = read_fit(args.fit) if args.fit else None
        road = read_road(args.road) if args.road else None
        html = report_html(ds, fit, road)
    except (DatasetError, ValueError, KeyError, TypeError) as exc:
        return fail(str(exc).strip('"'))
    except OSError as exc:
        return fail(f"{exc.filename}: {exc.strerror}")
    try:
        with new_file(out) as tmp:
            tmp.write_text(html, encoding="utf-8")
    except OSError as exc:
        return fail(f"cannot write {out}: {exc.strerror or exc}")
    print(f"report of {args.dataset} → {out} ({len(html.encode()) / 1e6:.1f} MB, self-contained)", file=sys.stderr)
    return EXIT_OK


def add_subcommand(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `rig report`."""
    p = subparsers.add_parser("report", help="a self-contained HTML measurement report of a dataset (figures "
                                             "embedded; print it to PDF from a browser)")
    p.add_argument("dataset", metavar="DATASET", help="dataset folder")
    p.add_argument("--out", required=True, metavar="report.html", help="output HTML file; never overwritten")
    p.add_argument("--fit", metavar="FIT.json", help="a fit written by `rig fit DATASET --model NAME --json`")
    p.add_argument("--road", metavar="road.json", help="road-lighting quantities written by "
                                                       "`rig export DATASET --format road`")
    p.set_defaults(func=cmd_report)
