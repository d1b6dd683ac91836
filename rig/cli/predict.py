"""`rig predict DATASET --at DIRECTIONS.csv --out PRED.csv [--method interpolate|model] [--fit FIT.json | --model M]`:
the BRDF and its standard uncertainty at arbitrary directions (rig.analysis.predict)."""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np

from rig.analysis.held_out import interpolating_predictor
from rig.analysis.predict import model_predictor
from rig.analysis.prediction import Prediction, Predictor
from rig.analysis.result_files import read_fit
from rig.core.exits import EXIT_OK, fail
from rig.core.interrupts import interruptible
from rig.data.dataset_format import DatasetError
from rig.data.dataset_reader import Dataset, load
from rig.data.output_folder import new_file

ANGLES = ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg")
COLUMNS = (*ANGLES, "brdf_per_sr", "u_brdf_per_sr", "extrapolated")
#: Bounds of each angle column of DIRECTIONS.csv (degrees; θ up to 90 inclusive, φ any finite value).
THETA_MAX_DEG = 90.0


class DirectionsError(ValueError):
    """DIRECTIONS.csv cannot be read; the message names the file, the line and the column."""


def read_directions(path: Path) -> np.ndarray:
    """(N, 4) degrees from a CSV with a header naming the four angle columns (in any order, others ignored)."""
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            reader = csv.DictReader(fh)
            missing = [c for c in ANGLES if c not in (reader.fieldnames or [])]
            if missing:
                raise DirectionsError(f"{path}: line 1: the header must name {', '.join(ANGLES)}; "
                                      f"missing {', '.join(missing)}")
            rows = []
            for row in reader:
                values = []
                for c in ANGLES:
                    try:
                        v = float(row[c])
                    except (TypeError, ValueError):
                        raise DirectionsError(f"{path}: line {reader.line_num}: {c} = {row[c]!r} is not a number") \
                            from None
                    if not np.isfinite(v) or (c.startswith("theta") and not 0.0 <= v <= THETA_MAX_DEG):
                        raise DirectionsError(f"{path}: line {reader.line_num}: {c} = {v:g} is not allowed "
                                              f"({'0 to 90' if c.startswith('theta') else 'finite'} degrees)")
                    values.append(v)
                rows.append(values)
    except UnicodeDecodeError as exc:
        raise DirectionsError(f"{path}: not a UTF-8 text file ({exc.reason})") from None
    if not rows:
        raise DirectionsError(f"{path}: no direction after the header")
    return np.array(rows, float)


def predictor_for(ds: Dataset, method: str, fit_path: str | None, model: str | None) -> Predictor:
    """The predictor of `rig predict` and `rig export --format road`; ValueError naming what is missing."""
    if len(ds) == 0:
        raise ValueError(f"{ds.path}: no measured point to predict from (brdf.csv holds no row)")
    if method == "interpolate":
        if fit_path or model:
            raise ValueError("--fit and --model go with --method model")
        return interpolating_predictor(ds)
    return model_predictor(ds, read_fit(fit_path) if fit_path else None, model, source=str(fit_path))


def _write_predictions(out: Path, directions: np.ndarray, p: Prediction) -> None:
    """PRED.csv, written under a temporary name and named when complete (rig.data.output_folder.new_file)."""
    with new_file(out) as tmp, tmp.open("w", newline="", encoding="utf-8") as fh:
        writer = csv.writer(fh, lineterminator="\n")
        writer.writerow(COLUMNS)
        for angles, f, u, x in zip(directions.tolist(), p.brdf_per_sr.tolist(), p.u_brdf_per_sr.tolist(),
                                   p.extrapolated.tolist()):
            writer.writerow([*angles, repr(f), repr(u), int(x)])


@interruptible
def cmd_predict(args: argparse.Namespace) -> int:
    out = Path(args.out)
    if out.exists():
        return fail(f"{out} already exists; choose another --out (nothing was overwritten)")
    try:
        ds = load(Path(args.dataset))
        directions = read_directions(Path(args.at))
        method = args.method or ("model" if args.fit or args.model else "interpolate")
        predictor = predictor_for(ds, method, args.fit, args.model)
        p = predictor.predict(*directions.T)
    except (DatasetError, DirectionsError, ValueError, KeyError) as exc:
        return fail(str(exc))
    except OSError as exc:
        return fail(f"{exc.filename}: {exc.strerror}")
    try:
        _write_predictions(out, directions, p)
    except OSError as exc:
        return fail(f"cannot write {out}: {exc.strerror or exc}")
    n_x = int(np.count_nonzero(p.extrapolated))
    print(f"predicted {len(directions)} directions → {out} ({predictor.method}); {n_x} extrapolated beyond the "
          f"measured domain", file=sys.stderr)
    return EXIT_OK


def add_subcommand(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `rig predict`."""
    p = subparsers.add_parser("predict", help="the BRDF and its uncertainty at arbitrary directions, from a "
                                              "dataset (interpolated) or a model fitted to it")
    p.add_argument("dataset", metavar="DATASET", help="dataset folder")
    p.add_argument("--at", required=True, metavar="DIRECTIONS.csv",
                   help="CSV with a header naming theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg (degrees, SCS)")
    p.add_argument("--out", required=True, metavar="PRED.csv", help="output CSV; never overwritten")
    p.add_argument("--method", choices=("interpolate", "model"), default=None,
                   help="interpolate (the default without --fit or --model): the measurements, no model assumed, "
                        "flagged beyond them; model (implied by --fit or --model): a fitted model (--fit FIT.json "
                        "from `rig fit --json`, or --model NAME to fit now), the only one that says anything beyond "
                        "the measured domain")
    p.add_argument("--fit", metavar="FIT.json", help="a fit written by `rig fit DATASET --model NAME --json`")
    p.add_argument("--model", help="fit this model to the dataset now (see `rig fit --help` for the models)")
    p.set_defaults(func=cmd_predict)
