"""`rig bench sampling`: the error of a dataset against the rig time it took, per strategy, on drawn samples.

For each drawn sample (rig.bench.draws: seeded families and parameter ranges, never a fixed handful) a campaign's
table (by default the paper's, Spieringhs et al. 2023, Tables 1 and 2) is measured on the simulated rig by:

- **table**: the table in table order with the fixed 5-exposure bracket (how the paper's rig measured);
- **table, optimised**: the same table in travel-optimised order with adaptive capture (rig's default);
- **adaptive ×f**: `sampling: {mode: adaptive}` over the same table as candidate domain, with a budget of f × the
  table's rig time after warm-up, for several f from far too few to more than enough (the curve must bend).

Each dataset's interpolant (`rig predict`'s, rig.analysis.held_out) is scored against the truth on validation
pairs it did not measure, **inside the table's measured domain** (rig.analysis.validation, `reference=`): where
the table itself extrapolates nobody is judged, and those pairs are reported apart as blind. Rig time is counted
after the lamp is stable (warm-up is the same for every strategy). Per draw: the smallest budget whose in-hull
p95 and road-quantity errors reach the table's (`reached`), and why not where none does (`why_not`).

Every campaign is a dask.distributed task (rig.bench.distributed): a draw's table run first, and when it is
done the draw's other strategies, which need its rig time (the budgets) and its measured domain (the scoring).
"""

from __future__ import annotations

import json
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from rig.acquisition.run import run_campaign
from rig.analysis.held_out import interpolating_predictor
from rig.analysis.predict import InterpolatingPredictor, measured_domain
from rig.analysis.validation import Domain, TruthPredictor, log_errors, representation_error, validation_set
from rig.bench.distributed import Failure, Task, run_tasks
from rig.bench.draws import Draw
from rig.config.campaign import Campaign, SimulatedBrdf
from rig.config.rigfile import RigConfig, SimulationConfig
from rig.data.dataset_reader import Dataset, load
from rig.session.adaptive_sampler import sampler_for
from rig.session.connect import open_campaign_rig

TABLE = "table"
OPTIMISED = "table, optimised"
#: Adaptive budgets as fractions of the table's rig time after warm-up: far too few to more than enough.
BUDGET_FRACTIONS = (0.05, 0.1, 0.175, 0.25, 0.35, 0.5)
#: The issue's bars: adaptive reaches the table's in-hull p95 by this fraction of its rig time on most draws...
TARGET_FRACTION = 0.25
#: ...and on every draw by this one.
EVERY_DRAW_FRACTION = 0.5
#: Road quantities may be this much (relative) worse than the table's and still count as reached.
ROAD_SLACK_REL = 0.002
#: ...and the p95 this much (in |ln|): a tenth of a percent, well below a point's own u (~0.3 %), which the
#: validation cannot resolve (a smooth sample's error is its points' noise, whatever the sampling).
P95_SLACK = 0.001
#: A verdict that is not reached counts the points measured within this many degrees of θi of the worst pairs.
NEAR_DEG = 5.0


@dataclass(frozen=True)
class WorstPairs:
    """Where a dataset's worst 5 % of validation pairs lie: median θi and θo (degrees), the share of them the
    interpolant can only extrapolate to, and how many measured points lie within NEAR_DEG of that θi."""

    theta_i_deg: float
    theta_o_deg: float
    outside_hull: float
    measured_near: int


@dataclass(frozen=True)
class Result:
    draw: str                     # Draw.name
    family: str
    seed: int
    strategy: str
    fraction: float | None        # the adaptive budget (× the table's rig time); None for the table strategies
    points: int
    rig_time_s: float             # after warm-up
    wall_s: float
    errors: dict[str, float]      # RepresentationError.row(), inside the table's measured domain
    worst: WorstPairs


def worst_pairs(predictor: InterpolatingPredictor, truth: TruthPredictor, angles_deg: np.ndarray,
                tau_per_sr: float, measured_theta_i_deg: np.ndarray) -> WorstPairs:
    a = angles_deg
    pred = predictor.predict(a[:, 0], a[:, 1], a[:, 2], a[:, 3])
    e = log_errors(pred.brdf_per_sr, truth.predict(a[:, 0], a[:, 1], a[:, 2], a[:, 3]).brdf_per_sr, tau_per_sr)
    worst = e >= np.quantile(e, 0.95)
    theta_i = float(np.median(a[worst, 0]))
    return WorstPairs(theta_i, float(np.median(a[worst, 2])), float(np.mean(pred.extrapolated[worst])),
                      int(np.sum(np.abs(measured_theta_i_deg - theta_i) <= NEAR_DEG)))


def measuring_time_s(folder: Path) -> float:
    """Rig time from the lamp being stable to the end of the run (events.jsonl)."""
    stable = end = 0.0
    for line in (folder / "events.jsonl").read_text().splitlines():
        event = json.loads(line)
        if event.get("event") == "warmup_stable":
            stable = float(event["rig_time_s"])
        if "rig_time_s" in event:
            end = max(end, float(event["rig_time_s"]))
    return end - stable


def domain_of(campaign: Campaign, rig: RigConfig) -> Domain:
    thetas = [t for entry in campaign.incidence for t in entry.theta]
    g = rig.geometry
    return Domain(min(thetas), max(thetas), campaign.limits.max_view_theta_deg,
                  float(np.degrees(np.arctan2(g.lamp_housing_radius_m, g.lamp_distance_m))))


def strategy_campaign(campaign: Campaign, drawn: Draw, strategy: str, budget_s: float | None = None) -> Campaign:
    """The campaign that measures `drawn` by `strategy` (TABLE, OPTIMISED, or adaptive with `budget_s`)."""
    sample = campaign.sample.model_copy(
        update={"simulated_brdf": SimulatedBrdf(model=drawn.family, params=drawn.params)})
    if strategy == TABLE:
        update: dict[str, Any] = {"ordering": "table",
                                  "capture": campaign.capture.model_copy(update={"mode": "fixed_bracket"})}
    elif strategy == OPTIMISED:
        update = {"ordering": "optimised"}
    else:
        update = {"sampling": campaign.sampling.model_copy(update={"mode": "adaptive", "budget_rig_time_s": budget_s})}
    return campaign.model_copy(update={"sample": sample, **update})


def measure(campaign: Campaign, drawn: Draw, strategy: str, fraction: float | None = None,
            table_rig_time_s: float | None = None, reference: Dataset | None = None) -> tuple[Result, Dataset]:
    """One strategy's campaign on the simulated rig (seeded by the draw: the same rig for every strategy) into a
    temporary folder, scored where the `reference` (the table's dataset; by default its own) measures; the
    result and the dataset. A dask task: everything it needs is in its arguments."""
    budget = None if fraction is None or table_rig_time_s is None else fraction * table_rig_time_s
    variant = strategy_campaign(campaign, drawn, strategy, budget)
    rig = RigConfig(simulation=SimulationConfig(seed=drawn.seed * 1000 + drawn.index))
    domain = domain_of(campaign, rig)
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "ds"
        wall0 = time.perf_counter()
        outcome = run_campaign(variant, rig, out, open_campaign_rig, sampler=sampler_for)
        wall = time.perf_counter() - wall0
        if outcome.status != "complete":
            raise RuntimeError(f"{drawn.describe()}, {strategy}: campaign {outcome.status}: {outcome.error}")
        ds, rig_time = load(out), measuring_time_s(out)
    measured = np.stack([ds[c] for c in ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg")], axis=1)
    vset = validation_set(domain, seed=drawn.seed * 1000 + drawn.index, measured_deg=measured)
    predictor = interpolating_predictor(ds)
    truth = TruthPredictor(drawn.family, drawn.params)
    ref = InterpolatingPredictor(measured_domain(reference)) if reference is not None else predictor
    err = representation_error(predictor, truth, vset, domain, reference=ref)
    inside = ~np.asarray(ref.predict(*vset.angles_deg.T).extrapolated, bool)
    worst = worst_pairs(predictor, truth, vset.angles_deg[inside], err.tau_per_sr, ds["theta_i_deg"])
    return Result(drawn.name, drawn.family, drawn.seed, strategy if fraction is None else f"adaptive ×{fraction:g}",
                  fraction, len(ds), rig_time, wall, err.row(), worst), ds


def study(client: Any, campaign: Campaign, drawn: Sequence[Draw], fractions: Sequence[float] = BUDGET_FRACTIONS,
          progress: Callable[[str], None] = lambda line: None) -> tuple[list[Result], list[Failure]]:
    """Every strategy on every draw as tasks on the client's workers (module docstring); the results in the order
    they finished and every failure, each naming its draw and seed."""
    def task(d: Draw, strategy: str, *extra: Any) -> Task:
        label = f"{d.describe()}: {f'adaptive ×{extra[0]:g}' if strategy == 'adaptive' else strategy}"
        return Task(label, measure, (campaign, d, strategy, *extra), {"draw": d.index, "seed": d.seed,
                                                                      "family": d.family, "strategy": strategy})

    by_name = {d.name: d for d in drawn}

    def then(done: Task, outcome: tuple[Result, Dataset]) -> list[Task]:
        result, ds = outcome
        if result.strategy != TABLE:
            return []
        d = by_name[result.draw]
        return [task(d, OPTIMISED, None, None, ds)] + [task(d, "adaptive", f, result.rig_time_s, ds)
                                                       for f in fractions]

    done, failures = run_tasks(client, [task(d, TABLE) for d in drawn], then, progress)
    return [outcome[0] for _, outcome in done], failures


def load_results(path: Path) -> list[Result]:
    """The results of a study's JSON (`rig bench sampling` writes sampling.json)."""
    rows = json.loads(path.read_text())["results"]
    return [Result(**{**r, "worst": WorstPairs(**r["worst"])}) for r in rows]
