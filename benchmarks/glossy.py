"""Benchmark: glossy and high-dynamic-range samples with and without the filter wheel.

For each sample — the glossy modified-Phong lobe (n = 3000, peak 382 sr⁻¹, tests/campaigns/e2e-glossy.yaml),
a mirror-like one (n = 30000), a near-black diffuse one, a diffuse one, the retroreflective RM1 and RM3 of
the end-to-end tests and, with `--paper`, the paper campaign — the campaign runs on the simulated rig with
the built-in filter wheel and on the same rig without it, over several seeds (independent simulated rigs);
a campaign that aligns the arm on the specular peak (`alignment`) also runs with the wheel but unaligned.
The table gives, per sample and rig: lower bounds (`roi_saturated` points), median and p95 |relative
error| against the ground truth, k = 2 coverage of the reported uncertainty, points flagged `narrow_lobe`,
filter moves, and the rig time with the wheel relative to the rig time without it in the same run.

    python benchmarks/glossy.py [--seeds N] [--paper] [--only TEXT]
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.bench.error_vs_time import machine  # noqa: E402
from rig.bench.truth import measured_with_truth  # noqa: E402
from rig.config.campaign import Campaign, load_campaign  # noqa: E402
from rig.config.rigfile import RigConfig, SimulationConfig, simulated_rig  # noqa: E402

TESTS = ROOT / "tests" / "campaigns"


def with_sample(campaign: Campaign, name: str, model: str, params: dict[str, float]) -> Campaign:
    truth = campaign.sample.simulated_brdf
    assert truth is not None
    sample = campaign.sample.model_copy(update={"id": name, "simulated_brdf": truth.model_copy(
        update={"model": model, "params": params})})
    return campaign.model_copy(update={"name": name, "sample": sample})


def samples(paper: bool) -> dict[str, Campaign]:
    glossy = load_campaign(TESTS / "e2e-glossy.yaml")
    reduced = load_campaign(TESTS / "e2e-reduced.yaml")
    found = {
        "glossy n=3000": glossy,
        "mirror-like n=30000": with_sample(glossy, "mirror-like", "modified_phong", {"kd": 0.05, "ks": 0.8, "n": 3e4}),
        "near-black kd=0.01": with_sample(reduced, "near-black", "lambert", {"kd": 0.01}),
        "diffuse kd=0.8": with_sample(reduced, "diffuse", "lambert", {"kd": 0.8}),
        "retro RM1": reduced,
        "retro RM3 (steep)": load_campaign(TESTS / "e2e-steep.yaml"),
    }
    if paper:
        found["paper RM1"] = load_campaign(ROOT / "campaigns" / "spieringhs2023-rm1.yaml")
    return found


def run(campaign: Campaign, rig: RigConfig, out: Path) -> dict[str, float]:
    d, truth = measured_with_truth(campaign, rig, out)
    with (out / "brdf.csv").open() as f:
        rows = list(csv.DictReader(f))
    with (out / "events.jsonl").open() as f:
        moves = sum(1 for line in f if json.loads(line).get("event") == "filter") - 1   # the first is the start
    flags = [r["flags"].split(";") for r in rows]
    return {"rel": np.abs(d["brdf_per_sr"] / truth - 1), "z": (d["brdf_per_sr"] - truth) / d["u_brdf_per_sr"],
            "lower_bounds": sum("roi_saturated" in f for f in flags), "narrow": sum("narrow_lobe" in f for f in flags),
            "moves": max(moves, 0), "rig_time_s": float(rows[-1]["rig_time_s"]) if rows else 0.0}


def variants(campaign: Campaign) -> list[tuple[str, Callable[[], RigConfig], Campaign]]:
    """The rigs a sample runs on: with the wheel as the campaign says; with it but without the campaign's
    specular alignment (if it has one); without the wheel (no alignment: its scan would saturate)."""
    unaligned = campaign.model_copy(update={"alignment": None})
    found: list[tuple[str, Callable[[], RigConfig], Campaign]] = [("wheel", simulated_rig, campaign)]
    if campaign.alignment is not None:
        found.append(("wheel, unaligned", simulated_rig, unaligned))
    return found + [("no wheel", RigConfig, unaligned)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--paper", action="store_true", help="also the paper campaign (1865 points per run)")
    parser.add_argument("--only", default="", help="only the samples whose name contains this text")
    args = parser.parse_args()
    print(machine())
    print(f"seeds 1…{args.seeds}; rigs: built-in simulated rig with its ND wheel (open, ND 1–5) and the same "
          "rig without it")
    header = (f"{'sample':22s} {'rig':16s} {'points':>6s} {'lower':>5s} {'med|rel|':>8s} {'p95|rel|':>8s} "
              f"{'cov k=2':>7s} {'narrow':>6s} {'moves':>5s} {'rig time':>9s}")
    print(header)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for name, campaign in samples(args.paper).items():
            if args.only not in name:
                continue
            times: dict[str, float] = {}
            for label, rig_of, variant in variants(campaign):
                results = []
                for seed in range(1, args.seeds + 1):
                    rig = rig_of().model_copy(update={"simulation": SimulationConfig(seed=seed)})
                    results.append(run(variant, rig, Path(tmp) / f"{name}-{label}-{seed}".replace(" ", "_")))
                rel = np.concatenate([r["rel"] for r in results])
                z = np.concatenate([r["z"] for r in results])
                times[label] = sum(r["rig_time_s"] for r in results)
                ratio = "" if label != "no wheel" else f" ({times['wheel'] / times[label]:.4f}× with wheel)"
                print(f"{name:22s} {label:16s} {rel.size:6d} {sum(r['lower_bounds'] for r in results):5d} "
                      f"{np.median(rel):8.4f} {np.percentile(rel, 95):8.4f} {np.mean(np.abs(z) <= 2):7.3f} "
                      f"{sum(r['narrow'] for r in results):6d} {sum(r['moves'] for r in results):5d} "
                      f"{times[label]:8.0f}s{ratio}", flush=True)
    print(f"wall time {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
