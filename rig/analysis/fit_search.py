"""The global stage of rig.analysis.fit: where its local refinements start, and how many starts agree.

Why it is built this way: stiff models have basins a single local run cannot leave. A lobe too
narrow to be seen by any view (Blinn α → 1e5, ABC C → its bound, MRM f0 → 0 with the diffuse term
taking the signal) is a plateau: the gradient there is zero, so a start on it stays. Two searches
that fail differently are combined, both on a fixed subsample of the points so their cost does not
grow with the campaign:

* `differential_evolution` (Latin-hypercube population seeded with the model's typical values):
  a population crosses plateaus, but 20 generations leave it near, not at, the best basin;
* bounded `least_squares` from the best distinct members of that population, from the typical
  values and from a scrambled Sobol set of points spread over the whole cube (the paper fitted
  with a genetic algorithm; random restarts are how its result is checked): each ends in a basin,
  loosely; the basins within REFINE_WITHIN of the best are refined on all points, and the best of
  those is the optimum the fit reports.

Every unit-cube point, population and Sobol set comes from the caller's seeded generator, so a fit
is deterministic. The number of local runs that reached the best cost is reported: one of many
means the optimum was hard to find, and a check with more starts (benchmarks/fit_global.py) is due.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.optimize import OptimizeResult, differential_evolution, least_squares
from scipy.stats import qmc

#: Points the search works on; the refinement always uses all of them.
SEARCH_POINTS = 400
#: Of those, the rows with the highest values (the lobes' peaks), kept whatever the draw.
PEAK_POINTS = 100
#: differential_evolution population per free parameter, and its generations.
DE_POPSIZE, DE_MAXITER = 15, 20
#: Local runs from Sobol points spread over the cube (a power of two keeps the set balanced),
#: and from the best distinct population members.
SOBOL_STARTS, MEMBER_STARTS = 16, 4
#: Iterations of a search run per free parameter (scipy's default is 100): nearly all runs settle in
#: 10–80; one crawling along a plateau is cut, and the refinement on all points finishes the best.
SEARCH_NFEV_PER_PARAM = 50
#: Their tolerances (scipy's default 1e-8): a search run only has to find its basin.
SEARCH_TOL = 1e-5
#: Starts closer than this on the unit cube (max norm) are the same start.
DISTINCT = 1e-3
#: Runs within this relative cost of the best one, or within this fraction of the cost of a
#: zero model (exact data have a best cost of ~0), count as having found it.
SAME_COST_REL, SAME_COST_ABS = 1e-4, 1e-12
#: Optima refined on all points: those within this factor of the subsample's best cost (the subsample
#: ranks basins within a fraction of a percent: RM3's Blinn-Retro, 0.14 % apart, swapped).
REFINE_WITHIN = 1.05
#: Optima whose costs differ by less than this (relative) are taken as one basin. The search's runs stop at
#: SEARCH_TOL, so the optima of one valley or plateau differ in cost by up to about 1e-4: at 1e-7, four points of
#: one valley (RM2's modified Phong on a subsample: a lobe at n ≈ 5300, ks 0.72–0.96, costs 1e-5 apart) took the
#: four refinements, and the basin the whole campaign wants (n ≈ 68, 2e-4 above them on the subsample) was never
#: refined: 1.2 % above the best of 20 random starts (benchmarks/fit_global.py).
SAME_BASIN = 1e-4

Residuals = Callable[[np.ndarray], np.ndarray]


@dataclass(frozen=True)
class SearchResult:
    """The search's optima on the subsample, best first and distinct, and the agreement of its runs."""

    optima: list[np.ndarray]
    n_runs: int
    n_at_best: int


def distinct(points: list[np.ndarray], n: int, costs: np.ndarray | None = None) -> list[np.ndarray]:
    """The first n points that differ from every earlier chosen one by more than DISTINCT and, when
    `costs` are given, in cost by more than SAME_BASIN: optima on one plateau (a lobe too narrow to
    see, at any width beyond some) have one cost, and refining more than one of them is wasted."""
    chosen: list[int] = []
    for i, x in enumerate(points):
        if len(chosen) == max(n, 1):
            break
        if all(np.max(np.abs(x - points[c])) > DISTINCT
               and (costs is None or abs(costs[i] - costs[c]) > SAME_BASIN * abs(costs[c])) for c in chosen):
            chosen.append(i)
    return [points[i] for i in chosen]


def n_at_best(costs: np.ndarray, zero_model_cost: float) -> int:
    """How many runs reached the lowest cost (to SAME_COST_REL, or SAME_COST_ABS of a zero model's)."""
    return int(np.sum(costs <= costs.min() * (1 + SAME_COST_REL) + SAME_COST_ABS * zero_model_cost))


def local_run(residuals: Residuals, x0: np.ndarray, loss: str, scale: float, solver: str,
              max_nfev: int | None = None, tol: float = 1e-8) -> OptimizeResult:
    """Bounded least_squares on the unit cube.

    LSMR for the many starts: the dense solver's SVD of the (N × k) Jacobian at every iteration runs
    on multithreaded BLAS and costs more than the model (5–50× on a loaded 2-core machine); the final
    polish is dense ("exact"): a few iterations, and it settles flat directions. One parameter is always
    dense: scipy 1.17's LSMR path indexes a 2-D subspace that one parameter does not have (IndexError
    from a start near a bound).
    """
    return least_squares(residuals, x0, bounds=(0.0, 1.0), loss=loss, f_scale=scale, max_nfev=max_nfev,
                         ftol=tol, xtol=tol, gtol=tol,
                         tr_solver="exact" if len(x0) == 1 else solver)


def search_rows(f: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """The SEARCH_POINTS rows the search works on: the highest values, then a random draw of the rest.

    A stiff parameter is a lobe's width, and a narrow lobe lights few points: a uniform draw of 400
    from a paper campaign's 1865 may keep too few of them to tell two widths apart (seen on RM3:
    Blinn-Retro's forward lobe settled at α 6.8e3 where all points want 4.5e4).
    """
    peak = np.argsort(f, kind="stable")[::-1][:PEAK_POINTS]
    rest = np.setdiff1d(np.arange(len(f)), peak)
    return np.sort(np.concatenate([peak, rng.choice(rest, SEARCH_POINTS - PEAK_POINTS, replace=False)]))


def search(residuals: Residuals, cost: Callable[[np.ndarray, float], float], scale_at: Callable[[np.ndarray], float],
           x_typical: np.ndarray, rng: np.random.Generator, loss: str, keep: int, zero_residuals: np.ndarray,
           ) -> SearchResult:
    """Global search of a k-parameter cube for the lowest `cost(residuals(x), scale)`.

    `residuals` works on the subsample; `scale_at(x)` is the robust loss's scale there (1 for a linear
    loss), estimated at the typical values for the population and at its best member for the local
    runs; `zero_residuals` are those of a zero model; `keep` distinct optima are returned, best first.
    """
    k = len(x_typical)
    scale = scale_at(x_typical)
    glob = differential_evolution(lambda x: cost(residuals(x), scale), [(0.0, 1.0)] * k, popsize=DE_POPSIZE,
                                  maxiter=DE_MAXITER, x0=x_typical, polish=False, seed=rng)
    scale = scale_at(glob.x)
    ranked = glob.population[np.argsort(glob.population_energies)]
    members = distinct([glob.x, x_typical, *ranked], MEMBER_STARTS + 1)
    spread = qmc.Sobol(k, scramble=True, seed=rng).random(SOBOL_STARTS)
    runs = [local_run(residuals, x0, loss, scale, "lsmr", SEARCH_NFEV_PER_PARAM * k, SEARCH_TOL)
            for x0 in (*members, *spread)]
    costs = np.array([cost(r.fun, scale) for r in runs])
    zero_cost = cost(zero_residuals, scale)
    order = np.argsort(costs, kind="stable")
    close = [i for i in order if costs[i] <= costs[order[0]] * REFINE_WITHIN + SAME_COST_ABS * zero_cost]
    return SearchResult(optima=distinct([runs[i].x for i in close], keep, costs[close]), n_runs=len(runs),
                        n_at_best=n_at_best(costs, zero_cost))
