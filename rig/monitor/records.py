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
from rig.core import events
from rig.data.campaign_runs import rig_time_shifts
from rig.physics.geometry import PLANE_TOL_DEG, plane_axes, plane_offsets, sph_to_vec
from rig.planning.estimate import NOMINAL_CAPTURE_S
from rig.planning.plan import build_plan, estimate_rig_time_s

#: Fields of an event left out of its one-line summary (shown apart, or too long).
SUMMARY_SKIP = frozenset({"event", "time_utc", "rig_time_s", "row", "identities", "readings", "point_ids"})
#: Longest summary of one event, characters.
SUMMARY_CHARS = 240
#: Longest `time_utc` taken as a time (ISO 8601 with microseconds and offset is 32 characters).
UTC_CHARS = 40


def text_of(value: Any) -> str | None:
    """A manifest's text field as the page shows it: None unless it is text."""
    return short_text(value) if isinstance(value, str) else None


def section(manifest: dict[str, Any], key: str) -> dict[str, Any]:
    """A section of the manifest; {} where it is absent or not an object."""
    value = manifest.get(key)
    return value if isinstance(value, dict) else {}


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
    estimate_s: float | None = None             # rig time of its points (moves and nominal captures)


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
                                     "to_measure": per_series[s.index]} for s in plan.series],
                       estimate_s=estimate_rig_time_s(plan, rig.axes, NOMINAL_CAPTURE_S))


class RunAxis:
    """Places each event on the campaign's rig-time axis and says which run wrote it (rig.data.campaign_runs):
    a run starts at the first event with a rig time after a `resume`; the rig times of a dataset written before
    rig time continued restarted at 0 there, and are shifted to follow the previous run."""

    def __init__(self) -> None:
        self.run, self.shift, self.reached = 0, 0.0, 0.0
        self._seen = self._resumed = False

    def place(self, kind: str, rig_s: float | None, manifest: dict[str, Any]) -> float | None:
        """`rig_s` of an event of `kind` on the campaign's axis (None stays None)."""
        if kind == events.RESUME:
            self._resumed = True
        if rig_s is None:
            return None
        if self._resumed and self._seen:
            self.run += 1
            shifts = rig_time_shifts(manifest)
            self.shift = self.reached if shifts is None else (shifts[self.run] if self.run < len(shifts) else 0.0)
        self._seen, self._resumed = True, False
        self.reached = max(self.reached, rig_s + self.shift)
        return rig_s + self.shift


class WarmupState:
    """The lamp's warm-up as its events tell it (rig.acquisition.warmup): when the lamp went on, the last check's
    reading and change, the rest expected; the manifest's run record gives the warm-up expected in all."""

    def __init__(self) -> None:
        self.on_s: float | None = None
        self.last: dict[str, Any] | None = None
        self.rest: tuple[float, float] | None = None        # (rig time, rest expected then) of the latest event

    def note(self, kind: str, event: dict[str, Any], rig_s: float | None, changes: list[dict[str, Any]],
             run: int) -> None:
        """Follow one event (of run `run`); a check's reading goes to `changes` for the page's E⊥ chart."""
        left = finite_float(event.get("expected_left_s"))
        if kind in (events.WARMUP_WAIT, events.WARMUP_CHECK) and rig_s is not None and left is not None:
            self.rest = (rig_s, left)
        if kind == events.LAMP_ON:
            self.on_s, self.last, self.rest = rig_s, None, None
        elif kind == events.WARMUP_CHECK:
            self.last = {"t": rig_s, "lx": finite_float(event.get("illuminance_lx")),
                         "change": finite_float(event.get("change_rel")),
                         "stable_below": finite_float(event.get("stable_rel")),
                         "left_s": finite_float(event.get("expected_left_s"))}
            changes.append({"k": "w", **self.last, "r": run})

    def state(self, manifest: dict[str, Any], rig_time_s: float | None) -> dict[str, Any]:
        """What the page says of the warm-up: expected (s, source), elapsed and the rest, the last check."""
        runs = manifest.get("runs")
        expected = section(runs[-1], "expected_warmup") if isinstance(runs, list) and runs and \
            isinstance(runs[-1], dict) else {}
        seconds = finite_float(expected.get("seconds"))
        elapsed = rig_time_s - self.on_s if rig_time_s is not None and self.on_s is not None else None
        left = max(seconds - elapsed, 0.0) if seconds is not None and elapsed is not None else None
        if self.rest is not None and rig_time_s is not None:
            left = max(self.rest[1] - (rig_time_s - self.rest[0]), 0.0)
        return {"expected_s": seconds, "source": text_of(expected.get("source")), "elapsed_s": elapsed,
                "left_s": left, "last": self.last}
