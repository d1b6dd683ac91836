"""What the monitor's page shows of one brdf.csv row, one event and the campaign's plan (rig.monitor.folder
follows the folder; these turn its lines into the page's records)."""

from __future__ import annotations

import json
import math
from collections import Counter
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

import numpy as np

from rig.config.campaign import parse_campaign
from rig.config.rigfile import RigConfig
from rig.physics.geometry import PLANE_TOL_DEG, plane_axes, plane_offsets, sph_to_vec
from rig.planning.plan import build_plan

#: Fields of an event left out of its one-line summary (shown apart, or too long).
SUMMARY_SKIP = frozenset({"event", "time_utc", "rig_time_s", "row", "identities", "readings", "point_ids"})
#: Longest summary of one event, characters.
SUMMARY_CHARS = 240
#: Longest `time_utc` taken as a time (ISO 8601 with microseconds and offset is 32 characters).
UTC_CHARS = 40


def finite_float(value: Any) -> float | None:
    """A cell or JSON value as a finite float; None where empty or not a number."""
    try:
        x = float(value)
    except (TypeError, ValueError, OverflowError):            # OverflowError: an integer beyond a float
        return None
    return x if math.isfinite(x) else None


def utc_seconds(text: Any) -> float | None:
    """An ISO 8601 UTC time as POSIX seconds; None if it is not one."""
    if not isinstance(text, str) or len(text) > UTC_CHARS:
        return None
    try:
        return datetime.fromisoformat(text).timestamp()
    except (ValueError, OverflowError):
        return None


def short_text(text: str, limit: int = SUMMARY_CHARS) -> str:
    """`text` cut to `limit` characters, with an ellipsis where it was cut."""
    return text if len(text) <= limit else text[:limit - 1] + "…"


def point_record(row: dict[str, Any]) -> dict[str, Any]:
    """What the page plots of one row (brdf.csv's text cells or a `point_pending` event's numbers).

    `x`: the signed viewing angle in the plane of incidence (degrees, + toward the lamp; as
    `rig plot` draws it: rig.physics.geometry.plane_offsets), None for a view farther than PLANE_TOL_DEG from
    the plane.
    """
    ti, pi, to, po = (finite_float(row.get(k)) or 0.0 for k in ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg"))
    t, n = plane_axes(ti, pi)
    wo = sph_to_vec(np.radians([to]), np.radians([po]))
    off, signed = plane_offsets(wo, t, n)
    series = finite_float(row.get("series"))
    return {"k": "p", "id": str(row.get("point_id", "")), "s": None if series is None else int(series),
            "ti": ti, "pi": pi, "to": to, "po": po, "f": finite_float(row.get("brdf_per_sr")),
            "u": finite_float(row.get("u_brdf_per_sr")), "t": finite_float(row.get("rig_time_s")),
            "x": float(signed[0]) if off[0] <= PLANE_TOL_DEG else None}


def summarize_event(event: dict[str, Any]) -> str:
    """One line of an event's fields for the list of recent events."""
    parts = []
    for key, value in event.items():
        if key in SUMMARY_SKIP:
            continue
        if isinstance(value, float):
            value = f"{value:.4g}"
        elif isinstance(value, (dict, list)):
            value = json.dumps(value, separators=(",", ":"))
        parts.append(f"{key}={value}")
    return short_text(" ".join(parts))


@dataclass
class PlanSummary:
    """What the campaign's plan says: the points to measure, and the incidence of each series."""

    to_measure: int | None = None
    series: list[dict[str, Any]] = field(default_factory=list)
    error: str | None = None


def plan_of(manifest: dict[str, Any]) -> PlanSummary:
    """The plan `rig run` measures, rebuilt from the manifest's campaign and rig configuration (as
    `--resume` does); at the end of a run the manifest's counts say the same."""
    try:
        campaign = parse_campaign(manifest["campaign"]["content"])
        rig = RigConfig.model_validate(manifest["rig"]["config"])
        plan = build_plan(campaign, rig)
    except (KeyError, TypeError, ValueError) as exc:
        return PlanSummary(error=f"no plan from the manifest ({str(exc).splitlines()[0][:200]})")
    per_series = Counter(p.series for p in plan.points)
    return PlanSummary(len(plan.points), [{"index": s.index, "theta_i_deg": s.theta_i_deg, "phi_i_deg": s.phi_i_deg,
                                     "to_measure": per_series[s.index]} for s in plan.series])
