"""Reading back what rig wrote for a later command: a fit (`rig fit --json`) for plot, export, predict and report,
and road.json (`rig export --format road`) for report. Anyone may have edited these files, so every value a
reader looks into is checked here, once: a wrong type is a `JsonFileError` naming the file and the key, never a
traceback further on."""

from __future__ import annotations

import math
import os
from typing import Any

from rig.core.jsonfile import JsonFileError, json_kind, read_json
from rig.physics.brdf_models import MODELS

#: A fit's entries that hold objects (analysis.fit.FitResult.to_json); null where not recorded.
FIT_OBJECTS = ("stderr", "covariance", "metrics", "diagnostics")
#: road.json's numbers the report shows (analysis.road.road_json), each with its u_ and null when undefined.
ROAD_NUMBERS = ("R_L_mcd_m2_lx", "Qd_mcd_m2_lx", "Q0", "S1")
ROAD_OBJECTS = ("surface_classes", "marking_classes")


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def _object(path: str | os.PathLike, what: str, hint: str) -> dict:
    value = read_json(path)
    if not isinstance(value, dict):
        raise JsonFileError(path, f"{json_kind(value)}, not {what}'s object ({hint})")
    return value


def _objects(path: str | os.PathLike, record: dict, keys: tuple[str, ...]) -> None:
    for key in keys:
        if not isinstance(record.get(key), dict | None):
            raise JsonFileError(path, f"{key!r} is {json_kind(record[key])}, not an object")


def read_fit(path: str | os.PathLike) -> dict:
    """One model's fit as `rig fit DATASET --model NAME --json` writes it: a known model, a finite number for each
    of its parameters, and numbers or null in stderr, metrics and covariance; JsonFileError naming what is not."""
    hint = "write it with `rig fit DATASET --model NAME --json`"
    fit = _object(path, "a fit", hint)
    if "fits" in fit:
        raise JsonFileError(path, f"the fits of `rig fit --model all`, not one model's fit ({hint})")
    model = fit.get("model")
    if not isinstance(model, str) or model not in MODELS:
        raise JsonFileError(path, f"'model' is {str(model)[:40]!r}, not one of {', '.join(sorted(MODELS))} ({hint})")
    params = fit.get("params")
    names = MODELS[model].param_names
    if not isinstance(params, dict) or set(params) != set(names) \
            or not all(_is_number(v) and math.isfinite(v) for v in params.values()):
        raise JsonFileError(path, f"'params' must give {', '.join(names)} of model {model} as finite numbers")
    _objects(path, fit, FIT_OBJECTS)
    rows = [fit.get("stderr") or {}, fit.get("metrics") or {}, *(fit.get("covariance") or {}).values()]
    for row in rows:
        if not isinstance(row, dict) or not all(v is None or _is_number(v) for v in row.values()):
            raise JsonFileError(path, "'stderr', 'metrics' and 'covariance' must hold numbers or null")
    return fit


def read_road(path: str | os.PathLike) -> dict:
    """road.json as `rig export DATASET --format road` writes it: its quantities numbers or null, its classes
    objects; JsonFileError naming what is not."""
    road = _object(path, "road.json", "write it with `rig export DATASET --format road`")
    for key in (*ROAD_NUMBERS, *(f"u_{k}" for k in ROAD_NUMBERS)):
        if not (road.get(key) is None or _is_number(road[key])):
            raise JsonFileError(path, f"{key!r} is {json_kind(road[key])}, not a number or null")
    _objects(path, road, ROAD_OBJECTS)
    return road
