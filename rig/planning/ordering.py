"""Travel-time ordering of a plan: fewer, shorter rig moves for the same points.

Pure and deterministic (no randomness, ties go to the lower index), so a resume
that rebuilds the plan gets the same order. The cost of a move is the rig's:
all four axes start together and the slowest one, plus its settling, sets the
time (trapezoidal profiles, `rig.core.motion`).

Series stay contiguous, because E⊥ is read once per series: the series are
ordered by stage travel, then the views of each series by nearest neighbour +
2-opt over the arm's moves, starting where the previous series ended. Each view
can be reached on either arm branch, (a, b) or (a ± 180°, -b); the tour is built
on the cheaper branch pair of every edge, then the cheapest consistent branch
sequence along the tour is chosen exactly (Viterbi).

Nearest neighbour + 2-opt over n nodes needs the n × n cost matrix and O(n²) work
per 2-opt pass. Up to BLOCK_NODES nodes (every series count and view count of the
paper campaigns) it runs on all of them at once; a longer path (a campaign with
thousands of incidences) is cut into blocks of consecutive nodes along a Hilbert
curve through the positions, each block ordered the same way from where the
previous one ended, so the time and the memory grow linearly with the nodes.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from rig.config.zones import ForbiddenZone
from rig.core.motion import move_time_s
from rig.physics import geometry as geo
from rig.planning.collisions import zone_at
from rig.planning.points import Plan, PlannedPoint, as_motors

if TYPE_CHECKING:
    from rig.config.rigfile import AxesConfig

#: Where the rig starts a campaign (home).
START_DEG = (0.0, 0.0, 0.0, 0.0)
#: A 2-opt move must gain more than this (seconds) to be taken: round-off never loops.
MIN_GAIN_S = 1e-9
#: Most nodes ordered at once by nearest neighbour + 2-opt; longer paths go block by block.
BLOCK_NODES = 200
#: Resolution of the Hilbert curve that sorts the nodes of a long path into blocks (bits per axis).
HILBERT_BITS = 16

#: cost(rows, cols): move times (len(rows), len(cols)) between the nodes with those indices.
CostFn = Callable[[np.ndarray, np.ndarray], np.ndarray]


def axis_parameters(axes: AxesConfig) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Speed, acceleration and settling time of the four axes, in AXIS_NAMES order."""
    cfg = [getattr(axes, name) for name in geo.AXIS_NAMES]
    return (np.array([c.speed_deg_s for c in cfg]), np.array([c.accel_deg_s2 for c in cfg]),
            np.array([c.settle_s for c in cfg]))


def travel_time_s(axes: AxesConfig, start_deg: ArrayLike, target_deg: ArrayLike) -> np.ndarray:
    """Duration of moves between positions (..., 4) that broadcast; NaN where a position is NaN.

    An axis that does not move adds nothing (no settling either). Axis by axis,
    so that cost matrices need no (n, n, 4) temporaries.
    """
    start, target = np.asarray(start_deg, float), np.asarray(target_deg, float)
    out = np.zeros(np.broadcast_shapes(start.shape, target.shape)[:-1])
    for k, (speed, accel, settle) in enumerate(zip(*axis_parameters(axes))):
        d = target[..., k] - start[..., k]
        out = np.maximum(out, np.where(d != 0, move_time_s(d, speed, accel) + settle, 0.0))
    return out


def path_time_s(axes: AxesConfig, start_deg: Sequence[float], positions_deg: np.ndarray) -> float:
    """Total move time from `start_deg` through `positions_deg` (n, 4) in order."""
    path = np.vstack([np.asarray(start_deg, float)[None, :], np.reshape(positions_deg, (-1, 4))])
    return float(np.sum(travel_time_s(axes, path[:-1], path[1:])))


def nearest_neighbour(from_start: np.ndarray, cost: np.ndarray) -> np.ndarray:
    """Open path from a start: always go to the cheapest unvisited node next."""
    n = len(cost)
    visited = np.zeros(n, bool)
    order = np.empty(n, int)
    row = from_start
    for k in range(n):
        nxt = int(np.argmin(np.where(visited, np.inf, row)))
        order[k], visited[nxt] = nxt, True
        row = cost[nxt]
    return order


def two_opt(from_start: np.ndarray, cost: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Improve an open path from a start (symmetric `cost`) by segment reversals until none gains.

    For each first position i every possible segment end j is evaluated at once;
    the best improving reversal is applied. The path end is free: a virtual end
    node costs nothing to reach.
    """
    n = len(order)
    full = np.zeros((n + 2, n + 2))            # nodes 0..n-1, start n, free end n+1
    full[:n, :n] = cost
    full[n, :n] = full[:n, n] = from_start
    path = np.concatenate([[n], order, [n + 1]])
    improved = True
    while improved:
        improved = False
        for i in range(1, n):
            # reverse path[i..j], j = i+1..n: edges (i-1, i) and (j, j+1) become (i-1, j) and (i, j+1)
            j = np.arange(i + 1, n + 1)
            a, b = path[i - 1], path[i]
            gain = full[a, b] + full[path[j], path[j + 1]] - full[a, path[j]] - full[b, path[j + 1]]
            best = int(np.argmax(gain))
            if gain[best] > MIN_GAIN_S:
                path[i:j[best] + 1] = path[i:j[best] + 1][::-1]
                improved = True
    return path[1:-1]


def open_path(from_start: np.ndarray, cost: np.ndarray) -> np.ndarray:
    """Nearest neighbour, then 2-opt."""
    return two_opt(from_start, cost, nearest_neighbour(from_start, cost))


def hilbert_order(xy: np.ndarray, bits: int = HILBERT_BITS) -> np.ndarray:
    """Indices of points (n, 2) along a Hilbert curve over their bounding square (ties: lower index).

    Consecutive points on the curve are close, and any run of them is compact: the blocks
    of a long path (`blocked_path`).
    """
    xy = np.asarray(xy, float)
    side = 1 << bits
    span = float(np.max(np.ptp(xy, axis=0)))
    q = np.minimum(np.floor((xy - xy.min(axis=0)) / (span or 1.0) * side), side - 1).astype(np.int64)
    x, y, d = q[:, 0], q[:, 1], np.zeros(len(q), np.int64)
    s = side >> 1
    while s:
        rx, ry = (x & s) > 0, (y & s) > 0
        d += s * s * ((3 * rx.astype(np.int64)) ^ ry.astype(np.int64))
        flip = ~ry & rx                                   # rotate the quadrant so the curve stays connected
        x, y = np.where(flip, side - 1 - x, x), np.where(flip, side - 1 - y, y)
        x, y = np.where(ry, x, y), np.where(ry, y, x)
        s >>= 1
    return np.argsort(d, kind="stable")


def blocked_path(from_start: np.ndarray, cost: CostFn, xy: np.ndarray) -> np.ndarray:
    """Open path through n nodes from a start: `open_path` on all of them up to BLOCK_NODES, else block
    by block.

    `from_start` (n,) are the move times from the start, `cost` gives the times between nodes and
    `xy` (n, 2) positions that are near where moves are short (for the Hilbert curve). Blocks are
    BLOCK_NODES-long runs along the curve, taken in the direction that begins nearer the start,
    each ordered from the end of the previous one: O(n · BLOCK_NODES) time and O(BLOCK_NODES²) memory.
    """
    n = len(from_start)
    if n <= BLOCK_NODES:
        every = np.arange(n)
        return open_path(from_start, cost(every, every))
    curve = hilbert_order(xy)
    if from_start[curve[-1]] < from_start[curve[0]]:
        curve = curve[::-1]
    path: list[np.ndarray] = []
    for block in np.array_split(curve, math.ceil(n / BLOCK_NODES)):
        entry = cost(path[-1][-1:], block)[0] if path else from_start[block]
        path.append(block[open_path(entry, cost(block, block))])
    return np.concatenate(path)


def arm_branches(motors_deg: np.ndarray, limits: geo.AxisLimits,
                 zones: Sequence[ForbiddenZone] = ()) -> np.ndarray:
    """Candidate positions (n, 3, 4) of the same directions: as given, then (a - 180°, -b), (a + 180°, -b).

    The camera direction Rz(a)·Ry(b)·z is the same on all of them; the
    alternatives are NaN where they leave the arm's limits or enter a zone.
    """
    m = np.asarray(motors_deg, float)
    out = np.repeat(m[:, None, :], 3, axis=1)
    out[:, 1, 2] -= 180.0
    out[:, 2, 2] += 180.0
    out[:, 1:, 3] *= -1.0
    lo = np.array([limits.arm_azimuth[0], limits.arm_polar[0]])
    hi = np.array([limits.arm_azimuth[1], limits.arm_polar[1]])
    unusable = np.any((out[:, 1:, 2:] < lo) | (out[:, 1:, 2:] > hi), axis=-1) | (zone_at(out[:, 1:], zones) != "")
    out[:, 1:][unusable] = np.nan
    return out


def _candidate_times(axes: AxesConfig, start: np.ndarray, target: np.ndarray) -> np.ndarray:
    """travel_time_s with unusable (NaN) candidates made infinitely expensive."""
    t = travel_time_s(axes, start, target)
    return np.where(np.isnan(t), np.inf, t)


def choose_branches(axes: AxesConfig, start_deg: np.ndarray, candidates: np.ndarray) -> np.ndarray:
    """Index (n,) of the candidate per point that makes the path through them, in order, fastest (Viterbi)."""
    first = _candidate_times(axes, start_deg, candidates[0])
    steps = _candidate_times(axes, candidates[:-1, :, None, :], candidates[1:, None, :, :])   # (n-1, K, K)
    best = first
    back = np.empty(steps.shape[::2], int)                                                     # (n-1, K)
    to = np.arange(candidates.shape[1])
    for k, step in enumerate(steps):
        total = best[:, None] + step
        back[k] = np.argmin(total, axis=0)
        best = total[back[k], to]
    chosen = np.empty(len(candidates), int)
    chosen[-1] = int(np.argmin(best))
    for k in range(len(back) - 1, -1, -1):
        chosen[k] = back[k, chosen[k + 1]]
    return chosen


def order_views(axes: AxesConfig, start_deg: np.ndarray, candidates: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Visiting order and branch per view of one series, from `start_deg`.

    The tour uses the cheaper branch pair of every edge (symmetric, so 2-opt
    applies); the branches are then fixed consistently along it.
    """
    from_start = np.min(_candidate_times(axes, start_deg, candidates), axis=1)

    def cost(rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        """Cheapest branch pair of every edge: (rows, cols, K, K) move times, least over the last two."""
        pairs = _candidate_times(axes, candidates[rows, None, :, None], candidates[None, cols, None, :])
        return pairs.min(axis=(2, 3))

    speed = axis_parameters(axes)[0]
    order = blocked_path(from_start, cost, candidates[:, 0, 2:] / speed[2:])     # the arm, in seconds of travel
    return order, choose_branches(axes, start_deg, candidates[order])


def order_series(axes: AxesConfig, start_deg: np.ndarray, stage_deg: np.ndarray) -> np.ndarray:
    """Visiting order of series at stage positions (S, 2): least stage travel from the start's stage."""
    def on_stage(x: np.ndarray) -> np.ndarray:
        return np.concatenate([x, np.zeros(x.shape[:-1] + (2,))], axis=-1)

    stage = on_stage(stage_deg)
    from_start = travel_time_s(axes, on_stage(np.asarray(start_deg, float)[:2]), stage)

    def cost(rows: np.ndarray, cols: np.ndarray) -> np.ndarray:
        return travel_time_s(axes, stage[rows, None], stage[None, cols])

    speed = axis_parameters(axes)[0]
    return blocked_path(from_start, cost, stage_deg / speed[:2])                 # the stage, in seconds of travel


def order_plan(plan: Plan, axes: AxesConfig, zones: Sequence[ForbiddenZone] = (),
               start: Sequence[float] = START_DEG, switch_branches: bool = True) -> Plan:
    """The plan with series and points reordered for least rig time; ids and angles unchanged.

    With `switch_branches` a point may move to its other arm branch when that is
    inside the limits and outside every forbidden zone. Empty series go last, in
    their given order.
    """
    limits = axes.limits()
    by_series: dict[int, list[PlannedPoint]] = {s.index: [] for s in plan.series}
    for p in plan.points:                       # one pass: the plan may hold thousands of series
        by_series[p.series].append(p)
    filled = [s for s in plan.series if by_series[s.index]]
    stage = np.array([by_series[s.index][0].motors_deg[:2] for s in filled]).reshape(-1, 2)
    series = [filled[k] for k in order_series(axes, np.asarray(start, float), stage)]
    here = np.asarray(start, float)
    points = []
    for s in series:
        pts = by_series[s.index]
        motors = np.array([p.motors_deg for p in pts])
        candidates = arm_branches(motors, limits, zones) if switch_branches else motors[:, None, :]
        order, branch = order_views(axes, here, candidates)
        chosen = candidates[order, branch]
        points += [replace(pts[k], motors_deg=as_motors(m)) for k, m in zip(order, chosen)]
        here = chosen[-1]
    empty = [s for s in plan.series if not by_series[s.index]]
    return replace(plan, series=tuple(series + empty), points=tuple(points))
