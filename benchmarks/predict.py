"""Benchmark: `rig predict`'s two methods against the simulated truth.

Each campaign runs on the built-in simulated rig; both predictors (the interpolant, and the sample's own
model family fitted to the dataset) are evaluated at random directions (θi uniform in 0–85°, θo uniform in
cos θo down to 85°, azimuths uniform), and the table gives, inside and outside the measured domain: the
fraction of directions, median and p95 |f̂/f − 1| and the k = 2 coverage of the stated u.

    python benchmarks/predict.py [--directions N] [--paper]
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
from rig.analysis.predict import InterpolatingPredictor, measured_domain, model_predictor  # noqa: E402
from rig.bench.error_vs_time import machine  # noqa: E402
from rig.config.campaign import load_campaign  # noqa: E402
from rig.config.rigfile import simulated_rig  # noqa: E402
from rig.data.dataset_reader import load  # noqa: E402
from rig.physics.brdf_models import get_model  # noqa: E402
from rig.physics.geometry import sph_to_vec  # noqa: E402
from rig.session.connect import open_campaign_rig  # noqa: E402


def directions(n: int, seed: int = 1) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    theta_o = np.degrees(np.arccos(rng.uniform(np.cos(np.radians(85.0)), 1.0, n)))
    return rng.uniform(0, 85, n), rng.uniform(0, 360, n), theta_o, rng.uniform(0, 360, n)


def stats(f: np.ndarray, u: np.ndarray, truth: np.ndarray, rows: np.ndarray) -> str:
    if not rows.any():
        return f"{0.0:6.2f} {'':>8s} {'':>8s} {'':>7s}"
    rel = np.abs(f[rows] / truth[rows] - 1)
    cov = np.mean(np.abs(f[rows] - truth[rows]) <= 2 * u[rows])
    return f"{rows.mean():6.2f} {np.median(rel):8.4f} {np.percentile(rel, 95):8.4f} {cov:7.3f}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--directions", type=int, default=5000)
    parser.add_argument("--paper", action="store_true", help="also the paper campaign (1865 points, ~1 min)")
    args = parser.parse_args()
    print(machine())
    print(f"{args.directions} random directions; simulated rig: the built-in one")
    print(f"{'campaign':24s} {'method':12s} {'inside':>6s} {'med|rel|':>8s} {'p95|rel|':>8s} {'cov k=2':>7s} | "
          f"{'outside':>6s} {'med|rel|':>8s} {'p95|rel|':>8s} {'cov k=2':>7s}")
    campaigns = [ROOT / "tests" / "campaigns" / "e2e-reduced.yaml"]
    if args.paper:
        campaigns.append(ROOT / "campaigns" / "spieringhs2023-rm1.yaml")
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for path in campaigns:
            campaign, rig = load_campaign(path), simulated_rig()
            out = Path(tmp) / path.stem
            run_campaign(campaign, rig, out, open_campaign_rig)
            ds = load(out)
            spec = campaign.sample.simulated_brdf
            assert spec is not None
            ti, pi_, to, po = directions(args.directions)
            truth = get_model(spec.model)(sph_to_vec(np.radians(ti), np.radians(pi_)),
                                          sph_to_vec(np.radians(to), np.radians(po)), spec.params)
            for label, predictor in (("interpolate", InterpolatingPredictor(measured_domain(ds))),
                                     (f"model {spec.model}", model_predictor(ds, model=spec.model))):
                p = predictor.predict(ti, pi_, to, po)
                print(f"{path.stem:24s} {label:12s} {stats(p.brdf_per_sr, p.u_brdf_per_sr, truth, ~p.extrapolated)} | "
                      f"{stats(p.brdf_per_sr, p.u_brdf_per_sr, truth, p.extrapolated)}", flush=True)
    print(f"wall time {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
