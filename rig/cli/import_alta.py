"""`rig import`: the command line of rig.data.importer."""

from __future__ import annotations

import argparse
import sys

from rig.core.exits import EXIT_OK, fail
from rig.core.interrupts import interruptible
from rig.core.jsonfile import read_json
from rig.data.alta import CONVERTIBLE_OUT, AltaError
from rig.data.dataset_format import DatasetError
from rig.data.importer import MISSING_PARAM_OUT_DEFAULT, import_alta


@interruptible
def cmd_import(args: argparse.Namespace) -> int:
    """Import, report the counts on stderr; bad input and unwritable output are exit code 2."""
    try:
        out = import_alta(args.alta_file, args.out, sample_id=args.sample_id,
                          assume_param_out=args.assume_param_out)
    except (AltaError, DatasetError) as exc:
        return fail(str(exc))
    except OSError as exc:
        return fail(f"{exc.filename}: {exc.strerror}")
    manifest = read_json(out / "dataset.json")          # as the import just wrote it
    counts = manifest["counts"]
    print(f"imported {args.alta_file} → {out}: {counts['measured']} points, {counts['skipped']} skipped "
          "(reasons in skipped.csv)", file=sys.stderr)
    for note in manifest["provenance"]["conversion"]:      # the uncertainty's k, #KEY lines skipped, ...
        print(f"  {note}", file=sys.stderr)
    return EXIT_OK


def add_subcommand(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `rig import ALTA_FILE --out DIR [--sample-id ID] [--assume-param-out KIND]`."""
    p = subparsers.add_parser("import", help="turn a measured ALTA text file into a rig dataset folder")
    p.add_argument("alta_file", metavar="ALTA_FILE", help="ALTA text file (#PARAM_IN ISOTROPIC_TL_TV_PROJ_DPHI "
                                                          "or SPHERICAL_TL_PL_TV_PV)")
    p.add_argument("--out", required=True, help="new dataset folder (must not exist or be empty)")
    p.add_argument("--sample-id", help="sample id for the manifest (default: the file's #SAMPLE, else its name)")
    p.add_argument("--assume-param-out", choices=CONVERTIBLE_OUT, default=MISSING_PARAM_OUT_DEFAULT,
                   help="output kind of a file without #PARAM_OUT (default: %(default)s)")
    p.set_defaults(func=cmd_import)
