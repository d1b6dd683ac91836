"""The manifest's account of a finished run: status, counts, uncertainty budget and angular footprint (pure)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from rig.acquisition.outcome import RunEnding
from rig.data.dataset_writer import utc_now
from rig.physics.budget import BUDGET_COLUMNS, campaign_budget
from rig.planning.points import Plan

#: Point ids listed by name in the manifest's footprint section, at most.
LISTED_POINTS = 50


def footprint_summary(rows: Sequence[Mapping[str, Any]], footprint_deg: float) -> dict[str, Any]:
    """What the run's values stand for on steep lobes: the angular footprint every ROI averages over, how
    many points were corrected to the ROI centre for the lobe's curvature, and which were `narrow_lobe`
    (a lobe narrower than the footprint: such a value is the footprint's average, corrected as far as the
    fit resolves it; measure them with a smaller ROI or a longer camera distance to know more)."""
    narrow = [str(r["point_id"]) for r in rows if "narrow_lobe" in str(r["flags"]).split(";")]
    return {"view_half_angle_deg": footprint_deg,
            "illumination_half_angle_deg": 0.0,      # the lamp beam is collimated: one incident direction
            "lobe_corrected_points": sum(1 for r in rows if float(r.get("lobe_bias_rel", 0.0)) != 0.0),
            "narrow_lobe_points": len(narrow), "narrow_lobe_point_ids": narrow[:LISTED_POINTS]}


def run_summary(ending: RunEnding, plan: Plan, measured: int, rows: Sequence[Mapping[str, Any]],
                footprint_deg: float, rig_time_s: float) -> dict[str, Any]:
    """The manifest keys the run writes when it ends (docs/dataset.md)."""
    return {"status": ending.status, "finished_utc": utc_now(), "rig_time_s": rig_time_s,
            "counts": {"planned": plan.n_planned, "measured": measured, "skipped": len(plan.skipped),
                       "not_measured": len(plan.points) - measured},
            "uncertainty_budget": campaign_budget(rows, BUDGET_COLUMNS),
            "footprint": footprint_summary(rows, footprint_deg),
            **({"error": ending.error} if ending.error else {})}
