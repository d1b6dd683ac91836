"""`rig export`: the command line of rig.data.export, and of the exports that need a predictor
(road-lighting quantities at their standard geometries: rig.analysis.road)."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

from rig.analysis.result_files import read_fit
from rig.analysis.road import export_road
from rig.cli.predict import predictor_for
from rig.core.exits import EXIT_OK, fail
from rig.core.interrupts import interruptible
from rig.data.dataset_format import DatasetError
from rig.data.dataset_reader import load
from rig.data.export import FORMATS, ExportError, export
from rig.data.output_folder import removed_on_failure
from rig.data.radiance import RadianceError, export_radiance, export_radiance_xml

#: Formats with options of their own (rig.data.radiance, rig.analysis.road).
OWN_FORMATS = ("radiance", "radiance-xml", "road")


def _export_road(args: argparse.Namespace) -> list[Path]:
    """road.json from a model fitted to the dataset: R_L lies at θi 88.76°, beyond what the rig measures,
    where only a model says anything (the interpolant would hold the nearest measured value)."""
    if not (args.fit or args.model):
        raise ValueError("--format road needs a model (--fit FIT.json from `rig fit --json`, or --model NAME): "
                         "R_L's geometry (θi 88.76°) lies beyond what the rig measures")
    out = Path(args.out)
    if out.exists():
        raise ExportError(f"{out} already exists; choose another --out (nothing was overwritten)")
    ds = load(Path(args.dataset))
    return [export_road(predictor_for(ds, "model", args.fit, args.model), out)]


def _export_radiance(args: argparse.Namespace) -> list[Path]:
    """pabopto2bsdf input (a folder), or a tensor-tree BSDF XML built by Radiance's own tools."""
    out = Path(args.out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ExportError(f"{out} already exists; choose another --out (nothing was overwritten)")
    ds = load(Path(args.dataset))
    with removed_on_failure(out):
        if args.format == "radiance":
            return export_radiance(ds, out, isotropic=not args.anisotropic)
        fit = read_fit(args.fit) if args.fit else None
        return export_radiance_xml(ds, out, source=args.source, fit=fit, isotropic=not args.anisotropic,
                                   resolution_log2=args.resolution)


def _export(args: argparse.Namespace) -> list[Path]:
    if args.format == "road":
        return _export_road(args)
    if args.format == "radiance-xml" and args.source == "model" and not args.fit:
        raise ValueError("--format radiance-xml --source model needs --fit FIT.json (`rig fit --json`)")
    if args.format in ("radiance", "radiance-xml"):
        return _export_radiance(args)
    if args.fit or args.model:
        raise ValueError("--fit and --model go with --format road or radiance-xml")
    return export(args.dataset, args.format, args.out, coverage_k=args.coverage_k)


@interruptible
def cmd_export(args: argparse.Namespace) -> int:
    """Export, say where on stderr (warnings too); bad input and unwritable output are exit code 2."""
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            paths = _export(args)
        for w in caught:
            print(f"rig: warning: {w.message}", file=sys.stderr)
    except (DatasetError, ExportError, RadianceError, ValueError) as exc:
        return fail(str(exc))
    except OSError as exc:
        return fail(f"{exc.filename}: {exc.strerror}")
    print(f"exported {args.dataset} as {args.format} → {args.out} ({len(paths)} file{'s' * (len(paths) > 1)})",
          file=sys.stderr)
    return EXIT_OK


def add_subcommand(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `rig export DATASET --format FORMAT --out PATH [--fit FIT.json | --model NAME]`."""
    p = subparsers.add_parser("export", help="write a dataset as ALTA, Radiance pabopto2bsdf input, CSV, "
                                             "per-point road-lighting quantities, or road.json at the standard "
                                             "geometries")
    p.add_argument("dataset", metavar="DATASET", help="dataset folder")
    p.add_argument("--format", required=True, choices=sorted({*FORMATS, *OWN_FORMATS}),
                   help="alta: ALTA text; radiance: folder of pabopto2bsdf files (one per incidence); radiance-xml: "
                        "a tensor-tree BSDF XML for renderers (Radiance's bsdf2ttree; the `radiance` extra); "
                        "csv: plain table; rl: q, R_L, r per point at the measured geometry; "
                        "road: R_L (30 m), Qd, the CIE r-table, Q0, S1 with uncertainties (road.json; needs a model)")
    p.add_argument("--out", required=True, help="output file (a new folder for radiance); never overwritten")
    p.add_argument("--fit", metavar="FIT.json", help="road, radiance-xml: the model fitted by `rig fit DATASET "
                                                     "--model NAME --json`")
    p.add_argument("--model", help="road: fit this model to the dataset now")
    p.add_argument("--source", choices=("data", "model"), default="data",
                   help="radiance-xml: from the measurements (pabopto2bsdf) or from the fitted model's formula "
                        "(--fit; a .cal for bsdf2ttree -f)")
    p.add_argument("--coverage-k", type=float, default=1.0, metavar="K",
                   help="alta: the vertical segments' half-width is K·u (ALTA's fitters take them as hard bounds; "
                        "K is written in a comment that `rig import` reads back; default 1)")
    p.add_argument("--anisotropic", action="store_true",
                   help="radiance, radiance-xml: keep each series at its φi (default: the sample is isotropic; each "
                        "series is turned to φi = 0 and series of one θi are merged, one file per incidence)")
    p.add_argument("--resolution", type=int, default=6, choices=range(4, 9), metavar="{4..8}",
                   help="radiance-xml: log2 of the tensor tree's resolution (default 6)")
    p.set_defaults(func=cmd_export)
