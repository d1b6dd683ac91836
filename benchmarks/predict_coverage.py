"""Benchmark: is `rig predict`'s uncertainty calibrated on samples nobody tuned it for? (issue 31)

Draws samples (rig.bench.draws) from five families with parameters drawn per seed over the ranges of the published
fits (docs/predict.md; the seed papers: Spieringhs et al. 2023 Table 7 RetroPhong, the MRM tape fit, glossy paints,
Oren–Nayar and Lambertian diffusers), measures each with the paper campaign's table
(campaigns/spieringhs2023-rm1.yaml) on the simulated rig, and compares the interpolant at random directions (θi ≤
88°, θo ≤ 85°) with the closed-form truth (the interpolant `rig predict` uses, rig.analysis.held_out): k = 2
coverage overall, inside the measured domain and among extrapolated directions, per draw and per family, with the
median |f̂/f − 1| and median relative u. A calibrated u covers about 95 % everywhere.

    python benchmarks/predict_coverage.py [--draws 20] [--directions 3000] [--seed 1]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.acquisition.run import run_campaign  # noqa: E402
from rig.analysis.held_out import interpolating_predictor  # noqa: E402
from rig.bench.draws import draw  # noqa: E402
from rig.bench.error_vs_time import machine  # noqa: E402
from rig.config.campaign import SimulatedBrdf, load_campaign  # noqa: E402
from rig.config.rigfile import simulated_rig  # noqa: E402
from rig.data.dataset_reader import load  # noqa: E402
from rig.physics.brdf_models import get_model  # noqa: E402
from rig.physics.geometry import sph_to_vec  # noqa: E402
from rig.session.connect import open_campaign_rig  # noqa: E402


def directions(n: int, seed: int) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    theta_i = np.degrees(np.arccos(rng.uniform(np.cos(np.radians(88.0)), 1.0, n)))
    theta_o = np.degrees(np.arccos(rng.uniform(np.cos(np.radians(85.0)), 1.0, n)))
    return theta_i, rng.uniform(0, 360, n), theta_o, rng.uniform(0, 360, n)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=20)
    parser.add_argument("--directions", type=int, default=3000)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    print(machine())
    print(f"{args.draws} drawn samples (seed {args.seed}) measured with the paper table; {args.directions} random "
          "directions each; k = 2 coverage of the interpolant's u against the closed-form truth")
    print(f"{'draw':>4s} {'family':15s} {'cov all':>7s} {'inside':>7s} {'extrap':>7s} {'n extr':>6s} "
          f"{'med|rel|':>8s} {'med u':>7s}")
    base, rig = load_campaign(ROOT / "campaigns" / "spieringhs2023-rm1.yaml"), simulated_rig()
    per_family: dict[str, list[np.ndarray]] = {}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.draws):
            drawn = draw(args.seed, k)
            family, params = drawn.family, drawn.params
            sample = base.sample.model_copy(update={"simulated_brdf": SimulatedBrdf(model=family, params=params)})
            campaign = base.model_copy(update={"sample": sample})
            out = Path(tmp) / f"draw{k}"
            run_campaign(campaign, rig, out, open_campaign_rig)
            ti, pi_, to, po = directions(args.directions, args.seed * 1000 + k)
            truth = get_model(family)(sph_to_vec(np.radians(ti), np.radians(pi_)),
                                      sph_to_vec(np.radians(to), np.radians(po)), params)
            p = interpolating_predictor(load(out)).predict(ti, pi_, to, po)
            covered = np.abs(p.brdf_per_sr - truth) <= 2 * p.u_brdf_per_sr
            rel, u_rel = np.abs(p.brdf_per_sr / truth - 1), p.u_brdf_per_sr / p.brdf_per_sr
            ext = p.extrapolated
            per_family.setdefault(family, []).append(np.column_stack([covered, ext]))
            print(f"{k:4d} {family:15s} {covered.mean():7.3f} {covered[~ext].mean():7.3f} "
                  f"{covered[ext].mean() if ext.any() else float('nan'):7.3f} {ext.sum():6d} {np.median(rel):8.4f} "
                  f"{np.median(u_rel):7.4f}", flush=True)
    print("per family (all draws pooled): coverage overall / inside / extrapolated")
    everything = np.concatenate([np.concatenate(v) for v in per_family.values()])
    for family, parts in per_family.items():
        c = np.concatenate(parts)
        print(f"  {family:15s} {c[:, 0].mean():.3f} / {c[~c[:, 1].astype(bool), 0].mean():.3f} / "
              f"{c[c[:, 1].astype(bool), 0].mean():.3f}")
    ext = everything[:, 1].astype(bool)
    print(f"  {'all':15s} {everything[:, 0].mean():.3f} / {everything[~ext, 0].mean():.3f} / "
          f"{everything[ext, 0].mean():.3f}")
    print(f"wall time {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
