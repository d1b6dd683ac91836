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
done the draw's other strategies, which need its rig time (the budgets) and its measured domain (the scoring);
earlier draws go first, so that a study cut short has whole draws.
"""

from __future__ import annotations

import json
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
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
from rig.core.events import ADAPTIVE_BATCH, WARMUP_STABLE
from rig.data.dataset_reader import Dataset, load
from rig.session.adaptive_sampler import sampler_for
from rig.session.connect import open_campaign_rig

TABLE = "table"
ADAPTIVE = "adaptive"
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
        if event.get("event") == WARMUP_STABLE:
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


def measure(campaign: Campaign, drawn: Draw, strategy: str, fractions: Sequence[float] = (),
            table_rig_time_s: float | None = None, reference: Dataset | None = None
            ) -> tuple[list[Result], Dataset]:
    """One strategy's campaign on the simulated rig (seeded by the draw: the same rig for every strategy) into a
    temporary folder, scored where the `reference` (the table's dataset; by default its own) measures; the
    results and the dataset. A dask task: everything it needs is in its arguments.

    Adaptive: one run with the largest budget, scored at each budget as the prefix of the batches that fit in it
    (`budget_prefixes`): a run with the smaller budget chooses the same batches up to there (the choice never
    depends on the budget, only whether a batch fits), and may then add one smaller batch that still fits; so
    each budget is scored on at most what its own run would measure."""
    budget = max(fractions) * table_rig_time_s if fractions and table_rig_time_s is not None else None
    variant = strategy_campaign(campaign, drawn, strategy, budget)
    rig = RigConfig(simulation=SimulationConfig(seed=drawn.seed * 1000 + drawn.index))
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "ds"
        wall0 = time.perf_counter()
        outcome = run_campaign(variant, rig, out, open_campaign_rig, sampler=sampler_for)
        wall = time.perf_counter() - wall0
        if outcome.status != "complete":
            raise RuntimeError(f"{drawn.describe()}, {strategy}: campaign {outcome.status}: {outcome.error}")
        ds, rig_time = load(out), measuring_time_s(out)
        prefixes = budget_prefixes(out, table_rig_time_s or 0.0, fractions) if budget is not None else []
    domain = domain_of(campaign, rig)
    ref = InterpolatingPredictor(measured_domain(reference)) if reference is not None else None
    if budget is None:
        return [score(ds, drawn, strategy, None, rig_time, wall, domain, ref)], ds
    results = []
    for f, left_out, prefix_time in prefixes:
        keep = np.array([pid not in left_out for pid in ds.point_id], bool)
        results.append(score(subset(ds, keep), drawn, f"adaptive ×{f:g}", f, prefix_time, wall, domain, ref))
    return results, ds


def score(ds: Dataset, drawn: Draw, strategy: str, fraction: float | None, rig_time_s: float, wall_s: float,
          domain: Domain, reference: InterpolatingPredictor | None) -> Result:
    """The dataset's interpolant (`rig predict`'s) against the truth where the reference measures."""
    measured = np.stack([ds[c] for c in ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg")], axis=1)
    vset = validation_set(domain, seed=drawn.seed * 1000 + drawn.index, measured_deg=measured)
    predictor = interpolating_predictor(ds)
    truth = TruthPredictor(drawn.family, drawn.params)
    ref = reference or predictor
    err = representation_error(predictor, truth, vset, domain, reference=ref)
    inside = ~np.asarray(ref.predict(*vset.angles_deg.T).extrapolated, bool)
    worst = worst_pairs(predictor, truth, vset.angles_deg[inside], err.tau_per_sr, ds["theta_i_deg"])
    return Result(drawn.name, drawn.family, drawn.seed, strategy, fraction, len(ds), rig_time_s, wall_s, err.row(),
                  worst)


def subset(ds: Dataset, keep: np.ndarray) -> Dataset:
    """The rows of `ds` where `keep`."""
    rows = np.flatnonzero(keep)
    return replace(ds, columns={c: v[keep] if isinstance(v, np.ndarray) else [v[k] for k in rows]
                                for c, v in ds.columns.items()},
                   point_id=[ds.point_id[k] for k in rows], flags=[ds.flags[k] for k in rows],
                   time_utc=[ds.time_utc[k] for k in rows])


def budget_prefixes(folder: Path, table_rig_time_s: float, fractions: Sequence[float]
                    ) -> list[tuple[float, set[str], float]]:
    """Per budget fraction f: the points of the adaptive batches that do not fit in f × the table's rig time
    (planned, as the sampler counts it) and the rig time after warm-up at which the batches that fit were done
    (when the next batch was chosen, after their closing E⊥ reading; the run's end after the last)."""
    events = [json.loads(line) for line in (folder / "events.jsonl").read_text().splitlines()]
    stable = next((float(e["rig_time_s"]) for e in events if e.get("event") == WARMUP_STABLE), 0.0)
    batches = [e for e in events if e.get("event") == ADAPTIVE_BATCH]
    total = measuring_time_s(folder)
    out = []
    for f in sorted(fractions):
        n = sum(1 for b in batches if float(b["planned_rig_time_s"]) <= f * table_rig_time_s)
        left_out = {pid for b in batches[n:] for pid in b["points"]}
        done_s = float(batches[n]["rig_time_s"]) - stable if n < len(batches) else total
        out.append((f, left_out, done_s))
    return out


def study(client: Any, campaign: Campaign, drawn: Sequence[Draw], fractions: Sequence[float] = BUDGET_FRACTIONS,
          progress: Callable[[str], None] = lambda line: None,
          record: Callable[[list[Result]], None] = lambda results: None) -> tuple[list[Result], list[Failure]]:
    """Every strategy on every draw as tasks on the client's workers (module docstring); the results in the order
    they finished and every failure, each naming its draw and seed. `record` gets each task's results as it
    finishes (a long study keeps what it has)."""
    def task(d: Draw, strategy: str, *extra: Any) -> Task:
        what = f"adaptive ×{'/'.join(f'{f:g}' for f in fractions)}" if strategy == ADAPTIVE else strategy
        return Task(f"{d.describe()}: {what}", measure, (campaign, d, strategy, *extra),
                    {"draw": d.index, "seed": d.seed, "family": d.family, "strategy": strategy},
                    priority=-10 * d.index + (strategy != TABLE))

    by_name = {d.name: d for d in drawn}

    def then(done: Task, outcome: tuple[list[Result], Dataset]) -> list[Task]:
        results, ds = outcome
        record(results)
        if results[0].strategy != TABLE:
            return []
        d = by_name[results[0].draw]
        return [task(d, OPTIMISED, (), None, ds), task(d, ADAPTIVE, tuple(fractions), results[0].rig_time_s, ds)]

    done, failures = run_tasks(client, [task(d, TABLE) for d in drawn], then, progress)
    return [r for _, outcome in done for r in outcome[0]], failures


def load_results(path: Path) -> list[Result]:
    """The results a study recorded as they finished (`rig bench sampling` writes results.jsonl, one per line)."""
    rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return [Result(**{**r, "worst": WorstPairs(**r["worst"])}) for r in rows]
