"""Benchmark: fit the simulated paper campaigns (Spieringhs 2023 RM1–RM3) like Tables 3 and 6.

Measures campaigns/spieringhs2023-rm{1,2,3}.yaml on the simulated rig (or reuses the
datasets in --dataset DIR/rm1, rm2, rm3, measuring only what is missing), then fits
RetroPhong and every registry model to each. Prints the machine and settings, a
Table-3-shaped table (RetroPhong per RM with the true Table 7 values and the relative
error beside), Table-6-shaped tables (all models per RM, best RMSE first, with the wall
time of each fit), and two same-run baselines so the numbers do not depend on how fast
this machine is today: the fit time in units of one model evaluation over the dataset,
and a plain bounded least_squares from the typical values in the natural parameters
(no log space, no global stage), with the parameter error it ends at.

The simulated sample *is* RetroPhong with Table 7 parameters plus measurement noise, so
the RetroPhong RMSE here is the noise level, not the paper's 0.10–0.28 sr⁻¹ model error.

    python benchmarks/fit_paper.py [--dataset DIR] [--repeat N] [--unweighted]

Targets: a RetroPhong fit of a paper campaign ≤ 2 s; all models ≤ 30 s.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.analysis.fit import FitResult, fit_dataset  # noqa: E402
from rig.analysis.fit_search import DE_MAXITER, DE_POPSIZE, SEARCH_POINTS, SOBOL_STARTS  # noqa: E402
from rig.bench.error_vs_time import machine  # noqa: E402
from rig.cli.fit import format_comparison  # noqa: E402
from rig.cli.main import main as rig_main  # noqa: E402
from rig.data.dataset_reader import Dataset, load  # noqa: E402
from rig.physics.brdf_models import MODELS  # noqa: E402

RMS = ("rm1", "rm2", "rm3")
#: Spieringhs et al. 2023 Table 7 (RetroPhong) and the paper's own goodness of fit (Table 3).
TABLE7 = {
    "rm1": {"kd": 0.620, "n": 24.0, "k1": 0.158, "k2": 0.0415, "k3": 0.00133, "k4": 5.47},
    "rm2": {"kd": 0.594, "n": 24.0, "k1": 0.0696, "k2": 0.0733, "k3": 6.58e-05, "k4": 8.74},
    "rm3": {"kd": 0.701, "n": 68.0, "k1": 0.184, "k2": 1.53e-12, "k3": 0.00570, "k4": 3.40},
}
#: RM3's k2 adds k2·(n+2)/(2π) ≈ 2e-11 sr⁻¹ at θi = 0 only, eight decades below the noise: not determinable.
BELOW_NOISE = {"rm3": {"k2"}}
PAPER_TABLE3 = {"rm1": (0.102, 0.0370, 0.879), "rm2": (0.106, 0.0201, 0.861), "rm3": (0.280, 0.0216, 0.814)}
TARGET_RETROPHONG_S, TARGET_ALL_S = 2.0, 30.0


def datasets(folder: Path) -> dict[str, Dataset]:
    """The three paper campaigns as datasets in folder/rmN, measured on the simulated rig if absent."""
    out = {}
    for rm in RMS:
        path = folder / rm
        if not (path / "dataset.json").exists():
            t0 = time.perf_counter()
            campaign = ROOT / "campaigns" / f"spieringhs2023-{rm}.yaml"
            if rig_main(["run", str(campaign), "--out", str(path), "--quiet"]) != 0:
                raise SystemExit(f"campaign {campaign} failed")
            print(f"measured {campaign.name} → {path} in {time.perf_counter() - t0:.1f} s")
        out[rm] = load(path)
    return out


def timed_fit(ds: Dataset, model: str, repeat: int, weighting: str) -> FitResult:
    """The fit, with the median wall time of `repeat` identical fits."""
    runs = [fit_dataset(ds, model, weighting=weighting) for _ in range(repeat)]
    return replace(runs[0], wall_s=statistics.median(r.wall_s for r in runs))


def one_evaluation_s(ds: Dataset, model: str) -> float:
    """Median time of one model evaluation over the whole dataset."""
    wi, wo = ds.directions()
    m = MODELS[model]
    times = []
    for _ in range(50):
        t0 = time.perf_counter()
        m(wi, wo, m.typical)
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def plain_least_squares(ds: Dataset, model: str, weighting: str, start: str) -> tuple[dict[str, float], float]:
    """Baseline: bounded least_squares in the natural parameters, no global stage, from `typical`
    (the RM1 values) or from the middle of the bounds."""
    m = MODELS[model]
    wi, wo = ds.directions()
    f = ds["brdf_per_sr"]
    sigma = ds["u_brdf_per_sr"] if weighting == "uncertainty" else np.ones_like(f)
    names = m.param_names
    lo, hi = (np.array(b) for b in zip(*(m.bounds[p] for p in names)))
    x0 = np.array([m.typical[p] for p in names]) if start == "typical" else (lo + hi) / 2
    t0 = time.perf_counter()
    res = least_squares(lambda p: (m.evaluate(wi, wo, **dict(zip(names, p))) - f) / sigma, x0, bounds=(lo, hi))
    return dict(zip(names, map(float, res.x))), time.perf_counter() - t0


def max_rel_error(params: dict[str, float], rm: str) -> float:
    """Largest relative error of the determinable kd, n, k1, k2, k4."""
    return max(abs(params[p] / TABLE7[rm][p] - 1) for p in ("kd", "n", "k1", "k2", "k4")
               if p not in BELOW_NOISE.get(rm, ()))


def table3(results: dict[str, FitResult]) -> str:
    """RetroPhong per RM: metrics, then fitted / true (relative error) per parameter."""
    names = MODELS["retrophong"].param_names
    head = f"{'RM':3s} {'RMSE':>9s} {'NRMSE':>9s} {'NCC':>7s}  " + "  ".join(f"{p:>27s}" for p in names)
    rows = [head, "-" * len(head)]
    for rm, r in results.items():
        m, truth = r.metrics, TABLE7[rm]
        cells = [f"{r.params[p]:9.4g}/{truth[p]:<9.3g}"
                 + ("(< noise)" if p in BELOW_NOISE.get(rm, ()) else f"({r.params[p] / truth[p] - 1:+7.1%})")
                 for p in names]
        rows.append(f"{rm[-1]:3s} {m['rmse']:9.3g} {m['nrmse']:9.3g} {m['ncc']:7.4f}  " + "  ".join(cells))
    rows.append("paper (measured data, model error): "
                + "; ".join(f"RM{rm[-1]} RMSE {a}, NRMSE {b}, NCC {c}" for rm, (a, b, c) in PAPER_TABLE3.items()))
    return "\n".join(rows)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dataset", metavar="DIR", help="folder with rm1/, rm2/, rm3/ datasets (measured if missing)")
    ap.add_argument("--repeat", type=int, default=3, help="fits of each, median wall time reported")
    ap.add_argument("--unweighted", action="store_true", help="fit the plain squared error (the paper's RMSE)")
    args = ap.parse_args()
    weighting = "none" if args.unweighted else "uncertainty"
    with tempfile.TemporaryDirectory() as tmp:
        data = datasets(Path(args.dataset) if args.dataset else Path(tmp))
        print(f"machine : {machine()}")
        print(f"settings: weighting {weighting}, loss linear, default starts; global stage differential_evolution "
              f"popsize {DE_POPSIZE}×k, ≤ {DE_MAXITER} generations, then local runs from its best members and "
              f"{SOBOL_STARTS} Sobol points, on ≤ {SEARCH_POINTS} points; "
              f"repeat {args.repeat}, median wall time")
        print("datasets: " + ", ".join(f"{rm} {len(ds)} points ({ds.path})" for rm, ds in data.items()))

        retro, retro_s, all_s, ok = {}, {}, {}, True
        for rm, ds in data.items():
            fits = [timed_fit(ds, name, args.repeat, weighting) for name in MODELS]
            retro[rm] = next(r for r in fits if r.model == "retrophong")
            retro_s[rm], all_s[rm] = retro[rm].wall_s, sum(r.wall_s for r in fits)
            print(f"\nTable 6 shape — {rm.upper()} ({len(ds)} points), all models, best RMSE first "
                  f"(wall s: median of {args.repeat}):")
            print(format_comparison(fits))
            print(f"all models: {all_s[rm]:.2f} s (target ≤ {TARGET_ALL_S:.0f} s)")

        print("\nTable 3 shape — RetroPhong, fitted / Table 7 truth (relative error):")
        print(table3(retro))

        print("\ntiming and same-run baselines (RetroPhong):")
        for rm, ds in data.items():
            t_eval = one_evaluation_s(ds, "retrophong")
            ok &= retro_s[rm] <= TARGET_RETROPHONG_S and all_s[rm] <= TARGET_ALL_S
            print(f"  {rm}: fit {retro_s[rm]:.2f} s (target ≤ {TARGET_RETROPHONG_S:.0f} s) = "
                  f"{retro_s[rm] / t_eval:.0f} × one evaluation over the dataset ({t_eval * 1e3:.2f} ms; "
                  f"{retro[rm].nfev} evaluations counted, mostly on the global stage's subsample); "
                  f"max error of the determinable kd, n, k1, k2, k4 {max_rel_error(retro[rm].params, rm):.2%}")
            for start in ("typical", "mid-bounds"):
                plain, t_plain = plain_least_squares(ds, "retrophong", weighting, start)
                print(f"       plain least_squares from {start:10s}: {t_plain:.2f} s "
                      f"(fit / plain {retro_s[rm] / t_plain:.1f}×), max error {max_rel_error(plain, rm):.2%}")
        print(f"\ntargets {'met' if ok else 'MISSED'}: RetroPhong ≤ {TARGET_RETROPHONG_S:.0f} s "
              f"(worst {max(retro_s.values()):.2f} s), all models ≤ {TARGET_ALL_S:.0f} s "
              f"(worst {max(all_s.values()):.2f} s)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
