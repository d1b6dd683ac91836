"""Planning scales about linearly with the points (defect 9: 10,000 incidence series took 339 s).

Not timed: the tests count operations, so they fail on a super-linear algorithm whatever the
machine: the move times the ordering evaluates (an n × n cost matrix over all series or views is
quadratic) and the Python lines run in rig.planning.plan, rig.planning.table and rig.planning.ordering (a scan
of every point per series is quadratic). Doubling the size may at most about double the count:
count(2N) ≤ 2.2 × count(N)
(a linear algorithm gives 2.0; before the fix the cost matrices and the angles between views grew
4×, the lines 2.5×).
"""

import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from rig.config.campaign import parse_campaign
from rig.config.rigfile import RigConfig
from rig.physics import geometry as geo
from rig.planning import ordering, plan, table
from rig.planning.ordering import (
    BLOCK_NODES,
    START_DEG,
    arm_branches,
    blocked_path,
    hilbert_order,
    open_path,
    order_series,
    order_views,
    travel_time_s,
)

RIG = RigConfig()
#: The real one, for the wrapper that counts its evaluations.
ANGLE_BETWEEN = geo.angle_between
#: Doubling the problem may at most about double the work (the counts are deterministic).
LINEAR = 2.2


def moves_evaluated(monkeypatch, fn: Callable[..., Any], *args: Any) -> tuple[int, Any]:
    """Number of move times rig.planning.ordering evaluates in fn(*args), and what it returns."""
    count = 0

    def counted(axes, start_deg, target_deg):
        nonlocal count
        out = travel_time_s(axes, start_deg, target_deg)
        count += out.size
        return out

    with monkeypatch.context() as m:
        m.setattr(ordering, "travel_time_s", counted)
        result = fn(*args)
    return count, result


def lines_run(fn: Callable[..., Any], *args: Any) -> tuple[int, Any]:
    """Number of Python lines run in rig/planning/plan.py, table.py and ordering.py in fn(*args), and what it
    returns."""
    files = {str(Path(module.__file__)) for module in (plan, table, ordering)}
    count = 0

    def local(frame, event, arg):
        nonlocal count
        count += event == "line"
        return local

    before = sys.gettrace()
    sys.settrace(lambda frame, event, arg: local if frame.f_code.co_filename in files else None)
    try:
        result = fn(*args)
    finally:
        sys.settrace(before)
    return count, result


def stage_positions(n: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.c_[rng.uniform(-85, 0, n), rng.uniform(-360, 0, n)]


def series_campaign(n: int):
    """n incidence series of four views each."""
    return parse_campaign({"name": f"scaling-{n}", "sample": {"id": "s"},
                           "incidence": [{"phi": 0, "theta": np.linspace(0.5, 80, n).round(9).tolist()}],
                           "viewing": [{"points": [[20, 90], [40, 270], [30, 180], [50, 0]]}]})


def test_series_ordering_evaluates_linearly_many_moves(monkeypatch):
    n = 2 * BLOCK_NODES
    counts = []
    for size in (n, 2 * n):
        count, order = moves_evaluated(monkeypatch, order_series, RIG.axes, START_DEG, stage_positions(size))
        counts.append(count)
        assert sorted(order) == list(range(size))
    assert counts[1] <= LINEAR * counts[0], counts


def test_view_ordering_evaluates_linearly_many_moves(monkeypatch):
    rng = np.random.default_rng(1)
    n = 2 * BLOCK_NODES
    counts = []
    for size in (n, 2 * n):
        motors = np.c_[np.full((size, 2), [-30.0, 0.0]), rng.uniform(-170, 170, size), rng.uniform(-85, 85, size)]
        candidates = arm_branches(motors, RIG.axes.limits())
        count, (order, branch) = moves_evaluated(monkeypatch, order_views, RIG.axes, np.zeros(4), candidates)
        counts.append(count)
        assert sorted(order) == list(range(size)) and np.all(np.isfinite(candidates[order, branch]))
    assert counts[1] <= LINEAR * counts[0], counts


def test_build_plan_runs_linearly_many_python_lines():
    """No per-series scan of all points (`p.series == s.index`) in planning or ordering."""
    counts = []
    for n in (60, 120):
        count, built = lines_run(plan.build_plan, series_campaign(n), RIG)
        counts.append(count)
        assert len(built.series) == n and built.n_planned == 4 * n
    assert counts[1] <= LINEAR * counts[0], counts


def path_cost(from_start: np.ndarray, cost: np.ndarray, order: np.ndarray) -> float:
    return float(from_start[order[0]] + cost[order[:-1], order[1:]].sum())


def grid_instance(n: int, seed: int = 2) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Stage positions (n, 2) in a shuffled, jittered grid, their move times from home and between them."""
    rng = np.random.default_rng(seed)
    side = int(np.ceil(np.sqrt(n)))
    grid = np.c_[np.repeat(np.arange(side), side), np.tile(np.arange(side), side)][:n] * [-8.0, -20.0]
    xy = rng.permutation(grid + rng.uniform(-1, 1, grid.shape))
    stage = np.c_[xy, np.zeros((n, 2))]
    return xy, travel_time_s(RIG.axes, START_DEG, stage), travel_time_s(RIG.axes, stage[:, None], stage[None, :])


def test_small_paths_are_ordered_as_one_block():
    xy, from_start, cost = grid_instance(BLOCK_NODES)
    got = blocked_path(from_start, lambda r, c: cost[np.ix_(r, c)], xy)
    np.testing.assert_array_equal(got, open_path(from_start, cost))


@pytest.mark.parametrize("n", [BLOCK_NODES + 1, 3 * BLOCK_NODES + 17])
def test_long_paths_go_block_by_block_nearly_as_short(n):
    xy, from_start, cost = grid_instance(n)
    got = blocked_path(from_start, lambda r, c: cost[np.ix_(r, c)], xy)
    assert sorted(got) == list(range(n))
    dense = path_cost(from_start, cost, open_path(from_start, cost))
    assert path_cost(from_start, cost, got) <= 1.05 * dense
    assert path_cost(from_start, cost, got) < 0.5 * path_cost(from_start, cost, np.arange(n))


@pytest.mark.parametrize("bits", [1, 3, 5])
def test_hilbert_order_steps_to_a_neighbour_on_a_full_grid(bits):
    side = 1 << bits
    xy = np.random.default_rng(bits).permutation(np.c_[np.repeat(np.arange(side), side),
                                                       np.tile(np.arange(side), side)].astype(float))
    order = hilbert_order(xy * 3.7 - 11.0, bits=bits)          # scale and offset do not matter
    assert sorted(order) == list(range(side * side))
    steps = np.abs(np.diff(xy[order], axis=0)).sum(axis=1)
    np.testing.assert_allclose(steps, 1.0)


def test_hilbert_order_keeps_ties_in_their_order():
    assert list(hilbert_order(np.zeros((3, 2)))) == [0, 1, 2]


def quadratic_first_of_repeats(dirs: np.ndarray) -> list[int]:
    """The rule by definition: keep a direction unless an earlier kept one is within SAME_DIRECTION_RAD."""
    keep: list[int] = []
    for k, d in enumerate(dirs):
        if not keep or np.all(geo.angle_between(dirs[keep], d) > table.SAME_DIRECTION_RAD):
            keep.append(k)
    return keep


def test_repeated_views_removed_by_the_rule_without_measuring_every_pair(monkeypatch):
    rng = np.random.default_rng(4)
    counts = []
    for n in (2000, 4000):
        base = rng.normal(size=(n, 3))
        dirs = base / np.linalg.norm(base, axis=1, keepdims=True)
        step = rng.normal(size=(len(dirs[::7]), 3))
        tiny = dirs[::7] + 3e-10 * step / np.linalg.norm(step, axis=1, keepdims=True)    # within the tolerance
        dirs = np.concatenate([dirs, dirs[::5], tiny / np.linalg.norm(tiny, axis=1, keepdims=True)])
        count = 0

        def counted(u, v):
            nonlocal count
            out = ANGLE_BETWEEN(u, v)
            count += np.size(out)
            return out

        with monkeypatch.context() as m:
            m.setattr(geo, "angle_between", counted)
            kept = table._first_of_repeats(dirs)
        counts.append(count)
        assert list(kept) == list(range(n))                          # the originals, in order
    assert counts[1] <= LINEAR * counts[0], counts
    small = np.concatenate([dirs[:300], dirs[-50:], dirs[n:n + 40]])
    assert list(table._first_of_repeats(small)) == quadratic_first_of_repeats(small)


def test_plan_of_more_series_than_a_block_keeps_every_point_and_beats_table_order():
    c = series_campaign(BLOCK_NODES + 50)
    table, optimised = plan.build_plan(c, RIG, ordering="table"), plan.build_plan(c, RIG)
    assert sorted(p.point_id for p in optimised.points) == sorted(p.point_id for p in table.points)
    assert optimised.skipped == table.skipped
    runs = [s for k, s in enumerate(p.series for p in optimised.points)
            if k == 0 or s != optimised.points[k - 1].series]
    assert runs == [s.index for s in optimised.series][:len(runs)] and len(set(runs)) == len(runs)
    assert plan.estimate_rig_time_s(optimised, RIG.axes, 0.0) < plan.estimate_rig_time_s(table, RIG.axes, 0.0)
