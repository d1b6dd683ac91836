"""Adaptive sampling: the next batch of an adaptive campaign, where it reduces the dataset's error most per second.

After the first pass (rig.planning.candidates), each batch is views at one incidence (a series: the stage moves
once, E⊥ is read once). For every unmeasured candidate the dataset's interpolant (rig.analysis.predict, the
predictor `rig predict` and the validation metric use), calibrated as `rig predict` calibrates it (its alignment
and between-incidence u from leave-one-incidence-out errors, rig.analysis.held_out.calibrate), gives its relative
uncertainty u/(f + τ) (τ as in rig.analysis.validation), at least `EXTRAPOLATED_U_REL` outside the measured θi
range. Measuring a view removes about that much error where the interpolant reads from it: the gain of a view is
u² (in the log-relative units of the validation error) times the span of θi its incidence stands for
(`represented_width_deg`: a new incidence in a wide gap serves more directions than one between close
neighbours). A calibrated u is what makes this an expected error reduction rather than a ranking: where the
held-out incidences show the between-incidence u too small, it is scaled up, and the sampler goes there.

The incidence's views are taken in order of gain, each taken view damping the gain of candidates within
`SPREAD_RADIUS` of it in the projected disk; the batch is the whole of that choice or its first half or
quarter, whichever gives the most gain per second (`series_batch`): the stage move and the E⊥ reading are paid
once per batch and each view adds its capture and the arm's travel, so a pattern is measured whole where the
reconstruction needs it whole, and in part where its other views would gain little. The batch chosen is the one
of largest gain per second of rig time from where the axes stand (moves in travel order, rig.planning.ordering;
a capture per point; an E⊥ reading per batch). This is the "uncertainty per cost" criterion the planning
literature suggests (Vávra & Filip 2017 adapt 1-D slices by their error; none of the prior work prices the
instrument's travel).

Gains and scores are compared in bins of `SCORE_BIN_LOG2` (a factor of 2^0.25), ties going to the lower series
and view: a point measured again after a resume differs from its first measurement by its noise, and that
must not change which points are chosen next (a resumed run ends with the same points as an uninterrupted one).
"""

from __future__ import annotations

from collections.abc import Collection, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rig.analysis.held_out import calibrate
from rig.analysis.predict import SAME_INCIDENCE_DEG, InterpolatingPredictor, measured_domain
from rig.analysis.validation import TAU_REL
from rig.config.rigfile import AxesConfig
from rig.config.zones import ForbiddenZone
from rig.data.dataset_reader import Dataset
from rig.physics import geometry as geo
from rig.planning.candidates import SAME_THETA_DEG
from rig.planning.ordering import order_plan, path_time_s
from rig.planning.points import Motors, Plan, PlannedPoint

#: u/(f + τ) of a candidate the interpolant can only extrapolate to (outside the measured hull or θi range).
EXTRAPOLATED_U_REL = 0.3
#: ...and at most this in a gain: an error of a factor e or more is "not known" however large the interpolant's u
#: (a sliver of a hull or a steep bend can state 20), and letting it count more would let one such candidate, and
#: the measurement noise it amplifies, decide the batch.
MAX_GAIN_U_REL = 1.0
#: The least span of θi (degrees) a series stands for (a candidate range of one incidence).
MIN_WIDTH_DEG = 1.0
#: A taken view damps the gain of candidates within this distance in the projected disk by (d/r)².
SPREAD_RADIUS = 0.03
#: A batch is its incidence's chosen views or the first of them in these shares, whichever scores best per second.
PARTIAL_SHARES = (1.0, 0.5, 0.25)
#: ...but never fewer views than this (a hull needs a few).
MIN_BATCH_VIEWS = 4
#: Scores and gains are compared in bins of this many octaves.
SCORE_BIN_LOG2 = 0.25


@dataclass(frozen=True)
class Batch:
    """The next points to measure and why: their series, the planned rig time, the sum of their gains, the
    score (gain per second), and the largest u/(f + τ) over all unmeasured candidates when it was chosen."""

    points: tuple[PlannedPoint, ...]
    series: int
    estimated_s: float
    gain: float
    score_per_s: float
    max_u_rel: float


def rows_dataset(rows: Sequence[Mapping[str, object]], planned: Mapping[str, PlannedPoint]) -> Dataset:
    """brdf.csv rows as written by the run (numbers) or read back on a resume (text) as a Dataset in memory, at
    their *planned* angles: the read-back scatters by the axes' resolution, and a choice must not depend on it
    (nor may a candidate drift in and out of the measured views' hull with it)."""
    def number(value: object) -> float:
        return float(value) if value not in ("", None) else float("nan")      # type: ignore[arg-type]

    points = [planned[str(r["point_id"])] for r in rows]
    columns = {c: np.array([number(r.get(c)) for r in rows], float) for c in ("brdf_per_sr", "u_brdf_per_sr")}
    for c in ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg"):
        columns[c] = np.array([getattr(p, c) for p in points], float)
    flags = [tuple(f for f in str(r.get("flags", "")).split(";") if f) for r in rows]
    return Dataset(path=Path("<run>"), manifest={}, columns=columns, point_id=[p.point_id for p in points],
                   flags=flags, time_utc=[str(r.get("time_utc", "")) for r in rows], skipped=[], header=())


def candidate_u_rel(rows: Sequence[Mapping[str, object]], points: Sequence[PlannedPoint],
                    planned: Mapping[str, PlannedPoint],
                    loo_cache: dict[bytes, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Each candidate's u/(f + τ): the interpolant's u (its measurements, the interpolation error within and
    between incidences), calibrated as `rig predict`'s is (rig.analysis.held_out.calibrate: the alignment and the
    between-incidence scale from leave-one-incidence-out errors, the scale binned like the scores so that a
    re-measured point's noise does not move it), at least EXTRAPOLATED_U_REL outside the measured θi range; and the
    measured incidences."""
    ds = rows_dataset(rows, planned)
    domain = measured_domain(ds, loo_cache=loo_cache)
    calibrate(domain)
    domain.theta_u_scale = float(binned(np.array(domain.theta_u_scale)))
    a = np.array([(p.theta_i_deg, p.phi_i_deg, p.theta_o_deg, p.phi_o_deg) for p in points], float).reshape(-1, 4)
    pred = InterpolatingPredictor(domain).predict(a[:, 0], a[:, 1], a[:, 2], a[:, 3])
    f = ds["brdf_per_sr"]
    tau = TAU_REL * float(np.median(f[np.isfinite(f)]))
    u_rel = pred.u_brdf_per_sr / (pred.brdf_per_sr + tau)
    within = domain.brackets(a[:, 0])[3]
    return np.where(within, u_rel, np.maximum(u_rel, EXTRAPOLATED_U_REL)), domain.theta_i_deg


def represented_width_deg(measured_deg: np.ndarray, theta_deg: float, range_deg: tuple[float, float]) -> float:
    """The span of θi a series at theta_deg stands for once measured: half the gap between the measured incidences
    on either side of it (the candidate range's ends where there are none). A view's gain counts for every θi the
    interpolant reads from it, so a new incidence in a wide gap is worth more than one between close neighbours."""
    below = measured_deg[measured_deg < theta_deg - SAME_THETA_DEG]
    above = measured_deg[measured_deg > theta_deg + SAME_THETA_DEG]
    lo = float(below.max()) if below.size else range_deg[0]
    hi = float(above.min()) if above.size else range_deg[1]
    return max((hi - lo) / 2, MIN_WIDTH_DEG)


def binned(x: np.ndarray) -> np.ndarray:
    """x rounded to bins of SCORE_BIN_LOG2 octaves (0 stays 0)."""
    x = np.asarray(x, float)
    with np.errstate(divide="ignore"):
        return np.where(x > 0, np.exp2(np.round(np.log2(np.where(x > 0, x, 1.0)) / SCORE_BIN_LOG2) * SCORE_BIN_LOG2),
                        0.0)


def spread_by_gain(points: Sequence[PlannedPoint], gain: np.ndarray, k: int) -> list[int]:
    """Indices of up to k views of one incidence: largest (binned) gain first, each damping its neighbours."""
    if not len(points):
        return []
    xy = geo.disk_coordinates(np.array([p.theta_o_deg for p in points]), np.array([p.phi_o_deg for p in points]),
                              points[0].phi_i_deg)
    g = binned(gain).astype(float)
    chosen: list[int] = []
    while len(chosen) < min(k, len(points)):
        best = int(np.argmax(np.where(np.isin(np.arange(len(points)), chosen), -1.0, g)))
        if g[best] <= 0:
            break
        chosen.append(best)
        d = np.hypot(*(xy - xy[best]).T)
        g = binned(g * np.minimum(1.0, (d / SPREAD_RADIUS) ** 2))
    return chosen


def choose_batch(rows: Sequence[Mapping[str, object]], candidates: Plan, measured: set[str], position: Motors,
                 axes: AxesConfig, zones: Sequence[ForbiddenZone], *, batch_points: int, capture_s: float,
                 reading_s: float, max_s: float = np.inf, pattern: Collection[str] | None = None,
                 loo_cache: dict[bytes, np.ndarray] | None = None) -> Batch | None:
    """The batch of best gain per second of rig time from `position` among those that take at most `max_s`; None
    when no candidate (or no batch that fits) is left. `pattern`: the candidates that are the table's own views
    (rig.planning.candidates.pattern_ids); at an incidence not measured yet the batch is these, whole (`new_series`).
    `loo_cache`: see rig.analysis.predict.measured_domain."""
    left = [p for p in candidates.points if p.point_id not in measured]
    if not left:
        return None
    u_rel, measured_deg = candidate_u_rel(rows, left, {p.point_id: p for p in candidates.points}, loo_cache)
    gain = np.minimum(u_rel, MAX_GAIN_U_REL) ** 2
    thetas = [p.theta_i_deg for p in candidates.points]
    theta_range = (min(thetas), max(thetas))
    by_series: dict[int, list[int]] = {}
    for k, p in enumerate(left):
        by_series.setdefault(p.series, []).append(k)
    best: Batch | None = None
    for series, idx in sorted(by_series.items()):
        theta = left[idx[0]].theta_i_deg
        shares: Sequence[float] = PARTIAL_SHARES
        if pattern is not None and not np.any(np.abs(measured_deg - theta) <= SAME_INCIDENCE_DEG):
            idx, shares = [k for k in idx if left[k].point_id in pattern], (1.0,)
            if not idx:
                continue
        pts = [left[k] for k in idx]
        width = represented_width_deg(measured_deg, theta, theta_range)
        batch = series_batch(candidates, series, pts, gain[idx], width, float(np.max(u_rel)), position, axes, zones,
                             batch_points, capture_s, reading_s, shares)
        if batch is None or batch.estimated_s > max_s:
            continue
        if best is None or binned(np.array(batch.score_per_s)) > binned(np.array(best.score_per_s)):
            best = batch
    return best


def series_batch(candidates: Plan, series: int, pts: Sequence[PlannedPoint], gain: np.ndarray, width: float,
                 max_u_rel: float, position: Motors, axes: AxesConfig, zones: Sequence[ForbiddenZone],
                 batch_points: int, capture_s: float, reading_s: float,
                 shares: Sequence[float] = PARTIAL_SHARES) -> Batch | None:
    """The batch of one incidence: its views of largest (spread) gain, as many as give the best gain per second
    among the whole choice and its first half and quarter (`PARTIAL_SHARES`; a tie keeps more views). The
    stage's move and the E⊥ reading are paid once per batch, each view adds its capture and the arm's travel:
    where the reconstruction still needs the whole pattern its low-gain views pay for themselves, and where it
    does not, they are left for a later batch. The choice does not depend on the budget (a batch is never cut
    to fit: the caller passes over one that does not)."""
    order = spread_by_gain(pts, gain, batch_points)
    best: Batch | None = None
    sizes = {min(len(order), max(MIN_BATCH_VIEWS, int(np.ceil(share * len(order))))) for share in shares}
    for k in sorted(sizes - {0}, reverse=True):
        chosen = order[:k]
        one = Plan(tuple(s for s in candidates.series if s.index == series), tuple(pts[i] for i in sorted(chosen)),
                   ())
        ordered = order_plan(one, axes, zones, position)
        moves = path_time_s(axes, position, np.array([p.motors_deg for p in ordered.points]))
        seconds = moves + capture_s * len(chosen) + reading_s
        g = width * float(np.sum(gain[chosen]))
        batch = Batch(ordered.points, series, seconds, g, g / seconds, max_u_rel)
        if best is None or binned(np.array(batch.score_per_s)) > binned(np.array(best.score_per_s)):
            best = batch
    return best
