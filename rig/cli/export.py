"""`rig export`: the command line of rig.data.export."""

from __future__ import annotations

import argparse
import sys

from rig.core.exits import EXIT_OK, fail
from rig.data.dataset_format import DatasetError
from rig.data.export import FORMATS, ExportError, export


def cmd_export(args: argparse.Namespace) -> int:
    """Export, say where on stderr; bad input and unwritable output are exit code 2."""
    try:
        paths = export(args.dataset, args.format, args.out)
    except (DatasetError, ExportError) as exc:
        return fail(str(exc))
    except OSError as exc:
        return fail(f"{exc.filename}: {exc.strerror}")
    print(f"exported {args.dataset} as {args.format} → {args.out} ({len(paths)} file{'s' * (len(paths) > 1)})",
          file=sys.stderr)
    return EXIT_OK


def add_subcommand(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `rig export DATASET --format alta|radiance|csv|rl --out PATH`."""
    p = subparsers.add_parser("export", help="write a dataset as ALTA, Radiance pabopto2bsdf input, CSV or "
                                             "road-lighting quantities (q, R_L, r)")
    p.add_argument("dataset", metavar="DATASET", help="dataset folder")
    p.add_argument("--format", required=True, choices=FORMATS,
                   help="alta: ALTA text; radiance: folder of pabopto2bsdf files (one per incidence); "
                        "csv: plain table; rl: q, R_L, r per point")
    p.add_argument("--out", required=True, help="output file (a new folder for radiance); never overwritten")
    p.set_defaults(func=cmd_export)
