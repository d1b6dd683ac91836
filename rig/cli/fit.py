"""`rig fit`: the command line of rig.analysis.fit (arguments, the printed report, the JSON file, exit codes)."""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import Any

from rig.analysis.fit import LOSSES, UNUSABLE_FLAGS, FitResult, choose_weighting, fit_dataset, usable_rows
from rig.core.exits import EXIT_OK, fail
from rig.core.interrupts import interruptible
from rig.data.dataset_format import DatasetError
from rig.data.dataset_reader import load
from rig.data.output_folder import new_file
from rig.physics.brdf_models import MODELS


def format_report(result: FitResult) -> str:
    """Parameters ± standard errors, the paper's metrics and the diagnostics, for people."""
    lines = [f"model {result.model}: {result.n_points} points, weighting {result.weighting}, loss {result.loss}"
             + (f" (scale {result.f_scale:.3g})" if result.f_scale is not None else "")]
    for name, value in result.params.items():
        se = result.stderr[name]
        note = ("fixed" if name in result.fixed else "± undetermined by the data" if not math.isfinite(se)
                else f"± {se:.3g}  ({se / abs(value):.2%})" if value else f"± {se:.3g}")
        lines.append(f"  {name:<8s} {value:12.6g}  {note}" + _shared(result, name)
                     + ("  [at bound]" if name in result.at_bound else ""))
    if any(_shared(result, name) for name in result.params):
        lines.append("  shared ±: the parameter's standard uncertainty from the errors all points share (the "
                     "calibrations, the axes' zeros), apart from the scatter's ± (docs/uncertainty.md)")
    m = result.metrics
    lines.append(f"RMSE {m['rmse']:.4g} sr⁻¹   NRMSE {m['nrmse']:.4g}   NCC {_fmt(m['ncc'], '.4f')}")
    lines.append(f"converged {_status(result)} ({result.message}); "
                 + (f"χ²/dof {result.chi2_dof:.3g}; " if result.chi2_dof is not None else "")
                 + f"{result.n_starts_at_best}/{result.n_starts} starts reached the best cost; "
                 f"{result.nfev} model evaluations; {result.wall_s:.2f} s")
    return "\n".join(lines)


def _shared(result: FitResult, name: str, relative: bool = True) -> str:
    """` shared ± u` of a parameter (its stderr_correlated; with `relative`, also as a share of the value), or
    nothing where no shared u moves it."""
    sc = result.stderr_correlated.get(name, 0.0)
    if name in result.fixed or not sc or not math.isfinite(sc):
        return ""
    value = result.params[name]
    return f" shared ± {sc:.3g}" + (f" ({sc / abs(value):.2%})" if relative and value else "")


def _fmt(v: float, spec: str) -> str:
    """A number, or a dash where it is not finite (NCC of a constant model)."""
    return format(v, spec) if math.isfinite(v) else "—"


def _status(result: FitResult) -> str:
    """'yes' only for an optimum inside the bounds: a solver that stopped on a bound has converged to the
    bound, which says the model cannot follow the data there, not that it found their optimum."""
    if not result.converged:
        return "NO"
    return "yes" if not result.at_bound else "at bound"


def format_comparison(results: list[FitResult]) -> str:
    """Table-6-like: one line per model, best RMSE first; parameters at a bound marked in the line."""
    head = (f"{'model':<16s} {'RMSE':>9s} {'NRMSE':>9s} {'NCC':>7s} {'wall s':>7s} {'conv':>8s} {'starts':>6s}"
            "  parameters")
    rows = [head, "-" * len(head)]
    for r in sorted(results, key=lambda r: r.metrics["rmse"]):
        m = r.metrics
        params = ", ".join(f"{k} {v:.3g}" + _shared(r, k, relative=False)
                           + (" [at bound]" if k in r.at_bound else "") for k, v in r.params.items())
        rows.append(f"{r.model:<16s} {m['rmse']:9.4g} {m['nrmse']:9.4g} {_fmt(m['ncc'], '7.3f'):>7s} "
                    f"{r.wall_s:7.2f} {_status(r):>8s} {f'{r.n_starts_at_best}/{r.n_starts}':>6s}  {params}")
    rows.append("")
    if any(r.at_bound for r in results):
        rows.append("[at bound]: the best fit lies on the parameter's limit, where the model cannot follow the data "
                    "(conv 'at bound', not 'yes')")
    if any(_shared(r, k) for r in results for k in r.params):
        rows.append("shared ±: a parameter's standard uncertainty from the errors all points share (calibrations, "
                    "the axes' zeros)")
    rows.append("starts: the global stage's local runs that reached the best cost, of all of them")
    return "\n".join(rows)


def _fixed_value(text: str) -> tuple[str, float]:
    """`--fix NAME=VALUE` as (name, value); argparse turns the error into a usage message."""
    name, _, value = text.partition("=")
    try:
        return name.strip(), float(value)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected NAME=VALUE, got {text!r}") from None


@interruptible
def cmd_fit(args: argparse.Namespace) -> int:
    """Fit, print the report (or the comparison of `--model all`), optionally write the JSON."""
    names = sorted(MODELS) if args.model == "all" else [args.model]
    if args.model != "all" and args.model not in MODELS:
        return fail(f"unknown model {args.model!r}; known: {', '.join(sorted(MODELS))}, or all")
    if args.json and Path(args.json).exists():
        return fail(f"{args.json} already exists; choose another --json (nothing was overwritten)")
    try:
        dataset = load(args.dataset)
    except (DatasetError, OSError) as exc:
        return fail(str(exc))
    exclude = UNUSABLE_FLAGS + tuple(args.exclude_flag)
    fixed = dict(args.fix)
    unknown = sorted(set(fixed).difference(*(MODELS[name].param_names for name in names)))
    if unknown:
        return fail(f"--fix {', '.join(unknown)}: no such parameter in {', '.join(names)}")
    keep = usable_rows(dataset, exclude)
    if len(dataset) == 0:
        return fail(f"{args.dataset}: no measured point to fit (brdf.csv holds no row)")
    if not keep.any():
        return fail(f"{args.dataset}: each of its {len(dataset)} points has one of the flags {', '.join(exclude)}: "
                    "no point left to fit")
    try:
        weighting, notice = choose_weighting(dataset["u_brdf_per_sr"][keep],
                                             [pid for pid, k in zip(dataset.point_id, keep) if k], args.weighting)
    except ValueError as exc:
        return fail(f"{args.dataset}: {exc}")
    if notice:
        print(f"rig fit: {args.dataset}: {notice}", file=sys.stderr)
    kwargs: dict[str, Any] = {"weighting": weighting, "loss": args.loss, "starts": args.starts, "seed": args.seed,
              "exclude_flags": exclude}
    try:
        results = [fit_dataset(dataset, name, fixed={k: v for k, v in fixed.items()
                                                     if k in MODELS[name].param_names}, **kwargs)
                   for name in names]
    except ValueError as exc:
        return fail(f"{args.dataset}: {exc}")
    print(f"rig fit: {dataset.path} ({len(dataset)} rows)")
    print(format_comparison(results) if args.model == "all" else format_report(results[0]))
    if args.json:
        out = ({"dataset": str(dataset.path), "fits": [r.to_json() for r in results]} if args.model == "all"
               else results[0].to_json())
        try:
            with new_file(Path(args.json)) as tmp:       # named when complete; never over an existing file
                tmp.write_text(json.dumps(out, indent=2, allow_nan=False) + "\n", encoding="utf-8")
        except OSError as exc:
            return fail(f"cannot write {args.json}: {exc.strerror or exc}")
    return EXIT_OK


def add_subcommand(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> argparse.ArgumentParser:
    """Register `rig fit DATASET --model NAME|all [--json OUT] [--weighted|--unweighted] [--loss L] ...`."""
    p = subparsers.add_parser("fit", help="fit a BRDF model (or all) to a dataset: parameters ± stderr, "
                                          "RMSE/NRMSE/NCC (Spieringhs 2023 Eqs. 16, 19, 20)")
    p.add_argument("dataset", help="dataset folder (contains dataset.json and brdf.csv)")
    p.add_argument("--model", required=True, help=f"one of {', '.join(sorted(MODELS))}, or all")
    p.add_argument("--json", metavar="OUT", help="also write the result as JSON (a new file: never overwritten)")
    weighting = p.add_mutually_exclusive_group()
    weighting.add_argument("--weighted", dest="weighting", action="store_const", const="uncertainty",
                           help="minimise χ² with u_brdf_per_sr; refused unless every row has u (default: "
                                "weighted when every row has u, unweighted with a notice when none has)")
    weighting.add_argument("--unweighted", dest="weighting", action="store_const", const="none",
                           help="minimise the plain squared error (the paper's RMSE), "
                                "even where u_brdf_per_sr is given")
    p.add_argument("--loss", choices=LOSSES, default="linear", help="robust loss against outliers (default linear)")
    p.add_argument("--starts", type=int, default=4,
                   help="the best distinct optima of the global stage that are refined on all points (default 4)")
    p.add_argument("--seed", type=int, default=0, help="seed of the global stage (default 0)")
    p.add_argument("--fix", type=_fixed_value, action="append", default=[], metavar="NAME=VALUE",
                   help="hold a parameter at a value (repeatable)")
    p.add_argument("--exclude-flag", action="append", default=[], metavar="FLAG",
                   help=f"also leave out rows with FLAG, e.g. grazing_incidence "
                        f"(always left out: {', '.join(UNUSABLE_FLAGS)})")
    p.set_defaults(func=cmd_fit)
    return p
