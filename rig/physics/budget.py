"""GUM uncertainty budget: per-point relative components and the campaign's summary table.

Each brdf.csv row carries the relative standard uncertainties (k = 1) of its
components; their root sum of squares matches u_brdf_per_sr / brdf_per_sr
(the block-based ROI uncertainty already holds noise and texture together).
The manifest gets, per component, how large it typically is and how much of
the combined variance it makes, largest first, so a lab sees what to improve.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

BUDGET_COLUMNS = {
    "u_rel_noise": "camera shot and read noise of the ROI mean (HDR merge)",
    "u_rel_dark": "noise of the subtracted dark frame(s)",
    "u_rel_texture": "ROI non-uniformity: sample texture and glints (block means minus noise)",
    "u_rel_calibration": "luminance calibration of the camera",
    "u_rel_illuminance": "E⊥: meter readings and meter calibration",
    "u_rel_drift": "lamp drift between E⊥ readings",
    "u_rel_angle": "incidence angle, through tan θi",
}


def campaign_budget(rows: Sequence[Mapping[str, float]], columns: Mapping[str, str]) -> list[dict]:
    """Per component: median and 95th percentile of its relative u, and its median share of u²."""
    if not rows:
        return []
    comp = {c: np.array([float(r[c]) for r in rows]) for c in columns}
    total_sq = np.sum([v ** 2 for v in comp.values()], axis=0)
    total_sq = np.where(total_sq > 0, total_sq, 1.0)
    table = [{"component": c, "meaning": columns[c],
              "median_u_rel": float(np.median(v)), "p95_u_rel": float(np.percentile(v, 95)),
              "median_share_of_variance": float(np.median(v ** 2 / total_sq))}
             for c, v in comp.items()]
    return sorted(table, key=lambda row: -row["median_share_of_variance"])
