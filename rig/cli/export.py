"""`rig export`: the command line of rig.data.export, and of the exports that need a predictor
(road-lighting quantities at their standard geometries: rig.analysis.road)."""

from __future__ import annotations

import argparse
import sys
import warnings
from pathlib import Path

import numpy as np

from rig.analysis.resampled import resampled
from rig.analysis.result_files import read_fit
from rig.analysis.road import road_json, road_quantities, shared_calibration_u_rel, write_road_json
from rig.analysis.smooth_views import smooth_predictor
from rig.cli.predict import predictor_for
from rig.core.exits import EXIT_OK, fail
from rig.core.interrupts import interruptible
from rig.data.dataset_format import DatasetError
from rig.data.dataset_reader import load
from rig.data.export import FORMATS, ExportError, export
from rig.data.materialx import export_materialx
from rig.data.output_folder import new_folder
from rig.data.radiance import RadianceError, export_radiance, export_radiance_xml
from rig.data.rtb import road_summary, write_rtb
from rig.data.zemax import FormulaPredictor, write_zemax

#: Formats with options of their own (rig.data.radiance, rig.analysis.road, rig.data.rtb, .materialx, .zemax).
OWN_FORMATS = ("materialx", "radiance", "radiance-xml", "road", "rtb", "zemax")
#: A model's Zemax table runs to this incidence (the data's, to the highest measured one).
ZEMAX_MODEL_THETA_MAX_DEG = 89.0


def _new_output(args: argparse.Namespace) -> Path:
    out = Path(args.out)
    if out.exists():
        raise ExportError(f"{out} already exists; choose another --out (nothing was overwritten)")
    return out


def _export_road(args: argparse.Namespace) -> list[Path]:
    """road.json (its values also on the terminal) or the DIALux r-table from a model fitted to the dataset: R_L
    lies at θi 88.76°, beyond what the rig measures, where only a model says anything (the interpolant would
    hold the nearest measured value)."""
    if not (args.fit or args.model):
        raise ValueError(f"--format {args.format} needs a model (--fit FIT.json from `rig fit --json`, or --model "
                         "NAME): R_L's geometry (θi 88.76°) and the r-table's grazing rows lie beyond what the rig "
                         "measures")
    out = _new_output(args)
    ds = load(Path(args.dataset))
    q = road_quantities(predictor_for(ds, "model", args.fit, args.model), correlated_u_rel=shared_calibration_u_rel(ds))
    if args.format == "rtb":
        return [write_rtb(road_json(q), out, ds.sample_id())]
    path = write_road_json(q, out)
    print("\n".join(road_summary(road_json(q))))
    return [path]


def _export_materialx(args: argparse.Namespace) -> list[Path]:
    """A MaterialX document of a fitted microfacet model; says on stderr which surface it used and why."""
    if not args.fit or args.model:
        raise ValueError("--format materialx needs --fit FIT.json (`rig fit DATASET --model mrm|mrm_diffuse|ggx "
                         "--json`), not --model")
    out = _new_output(args)
    result = export_materialx(read_fit(args.fit), out, load(Path(args.dataset)).sample_id(), str(args.fit))
    print(f"rig: {result.note}", file=sys.stderr)
    return [result.path]


def _export_zemax(args: argparse.Namespace) -> list[Path]:
    """A Zemax / LightTools tabular BSDF from the fitted model's formula or from the data's reconstruction."""
    if args.model or (args.source == "model") != bool(args.fit):
        raise ValueError("--format zemax: --source model takes --fit FIT.json (`rig fit --json`); --source data "
                         "(the default) takes neither --fit nor --model")
    out = _new_output(args)
    ds = load(Path(args.dataset))
    if args.fit:
        fit = read_fit(args.fit)
        result = write_zemax(FormulaPredictor(fit["model"], fit["params"]), out,
                             theta_max_deg=ZEMAX_MODEL_THETA_MAX_DEG,
                             comments=[f"sample {ds.sample_id()}: model {fit['model']} fitted by rig ({args.fit}), "
                                       + ", ".join(f"{k} = {v!r}" for k, v in fit["params"].items())])
        return [result.path]
    predictor = smooth_predictor(ds)
    result = write_zemax(predictor, out, theta_max_deg=float(np.round(np.max(ds["theta_i_deg"]), 1)),
                         comments=[f"sample {ds.sample_id()}: the measurements of {ds.path}", predictor.method])
    theta_worst, share = result.worst_share()
    print(f"rig: {result.extrapolated_cells} of {result.cells} cells above the horizon lie beyond the measured "
          f"domain (the reconstruction's extrapolation); they carry up to {share:.0%} of a row's albedo (θi "
          f"{theta_worst:g}°): what a reader integrates there was not measured (docs/zemax.md)", file=sys.stderr)
    return [result.path]


def _export_radiance(args: argparse.Namespace) -> list[Path]:
    """pabopto2bsdf input (a folder), or a tensor-tree BSDF XML built by Radiance's own tools."""
    out = Path(args.out)
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise ExportError(f"{out} already exists; choose another --out (nothing was overwritten)")
    ds = load(Path(args.dataset))
    if len(ds) == 0:                             # before anything is made of the points (e.g. resampled)
        raise RadianceError(f"{ds.path}: no measured point to export")
    if args.format == "radiance":
        with new_folder(out) as folder:          # renamed to --out when every file is there
            written = export_radiance(ds, folder, isotropic=not args.anisotropic)
        return [out / p.name for p in written]
    fit = read_fit(args.fit) if args.fit else None
    if args.source == "data" and not args.anisotropic:
        ds = resampled(ds)       # the reconstruction on a dense grid: pabopto2bsdf cannot follow sparse lobes
    return export_radiance_xml(ds, out, source=args.source, fit=fit, isotropic=not args.anisotropic,
                               resolution_log2=args.resolution)


def _export(args: argparse.Namespace) -> list[Path]:
    if args.format in ("road", "rtb"):
        return _export_road(args)
    if args.format in ("materialx", "zemax"):
        return _export_materialx(args) if args.format == "materialx" else _export_zemax(args)
    if args.format == "radiance-xml" and args.source == "model" and not args.fit:
        raise ValueError("--format radiance-xml --source model needs --fit FIT.json (`rig fit --json`)")
    if args.format in ("radiance", "radiance-xml"):
        return _export_radiance(args)
    if args.fit or args.model:
        raise ValueError("--fit and --model go with --format road, rtb, radiance-xml, materialx or zemax")
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
                                             "per-point road-lighting quantities, road.json at the standard "
                                             "geometries, a DIALux r-table, MaterialX or a Zemax tabular BSDF")
    p.add_argument("dataset", metavar="DATASET", help="dataset folder")
    p.add_argument("--format", required=True, choices=sorted({*FORMATS, *OWN_FORMATS}),
                   help="alta: ALTA text; radiance: folder of pabopto2bsdf files (one per incidence); radiance-xml: "
                        "a tensor-tree BSDF XML for renderers (Radiance's bsdf2ttree; the `radiance` extra); "
                        "csv: plain table; rl: q, R_L, r per point at the measured geometry; "
                        "road: R_L (30 m), Qd, the CIE r-table, Q0, S1 with uncertainties (road.json, and on the "
                        "terminal; needs a model); rtb: road.json's r-table as a DIALux .RTB file; materialx: an "
                        "mrm, mrm_diffuse or ggx fit as a MaterialX document (--fit); zemax: a Zemax/LightTools "
                        "tabular BSDF from the data or a fitted model (--source)")
    p.add_argument("--out", required=True, help="output file (a new folder for radiance); never overwritten")
    p.add_argument("--fit", metavar="FIT.json", help="road, rtb, radiance-xml, materialx, zemax: the model fitted by "
                                                     "`rig fit DATASET --model NAME --json`")
    p.add_argument("--model", help="road, rtb: fit this model to the dataset now")
    p.add_argument("--source", choices=("data", "model"), default="data",
                   help="radiance-xml, zemax: from the measurements (radiance-xml: pabopto2bsdf; zemax: the "
                        "reconstruction of rig predict) or from the fitted model's formula (--fit)")
    p.add_argument("--coverage-k", type=float, default=1.0, metavar="K",
                   help="alta: the vertical segments' half-width is K·u (ALTA's fitters take them as hard bounds; "
                        "K is written in a comment that `rig import` reads back; default 1)")
    p.add_argument("--anisotropic", action="store_true",
                   help="radiance, radiance-xml: keep each series at its φi (default: the sample is isotropic; each "
                        "series is turned to φi = 0 and series of one θi are merged, one file per incidence)")
    p.add_argument("--resolution", type=int, default=6, choices=range(4, 9), metavar="{4..8}",
                   help="radiance-xml: log2 of the tensor tree's resolution (default 6)")
    p.set_defaults(func=cmd_export)
