"""Benchmark: is a measured point's uncertainty calibrated, point by point, on samples nobody tuned it for? (issue 34)

Draws samples from the five families of rig.bench.draws (the reconstruction study's: RetroPhong, MRM + diffuse,
modified Phong, Oren–Nayar, Lambert, parameters over the published fits' ranges), measures each with the paper
campaign's table (campaigns/spieringhs2023-rm1.yaml) on its own simulated rig (seed = the draw's, so that every
error a run shares — the sample's grain, the filters' transmission errors, the axes' zero errors — is drawn anew),
and compares every measured point with the closed-form truth.

The point-to-point part is what a row's `u_brdf_point_per_sr` must cover: the error left once the errors shared
by the points are taken out. The shared ones here are the filters' transmissions (the simulator's camera and
meter are exact: campaigns/rigs/simulated.yaml), one per filter position, and the four axes' zero errors, each
through how the truth's f·cos θi changes with that axis at the point (`zero_error_columns`: tan θi through the
stage, and on a lobed sample the lobe's slope through every axis): a weighted fit of one relative shift per
filter position plus one angle per axis takes them out before z = (f/f_true − 1 − fit)/(u_point/f).
Per family: k = 2 coverage and std(z) of that part (calibrated: about 95 % and 1), the median |shift| against the
median correlated u (a shift the correlated part should cover), and z against the whole u. The same runs are scored
again against their exact truth (rig.bench.truth.measured_exactly: the BRDF where the axes physically were, the
filters' true transmissions divided out) with one shift for the run and nothing else fitted: fitted axis angles
also take a little of what the views share.

Then the issue's own kinds of sample, each on `--issue-seeds` simulated rigs of its own: the glossy modified Phong
n = 3000 measured through the ND wheel with an alignment on its peak (tests/campaigns/e2e-glossy.yaml) and the steep
RetroPhong RM3 to θi 85° (tests/campaigns/e2e-steep.yaml). The glossy sample's lobe goes through the wheel, so a
per-filter shift takes with it whatever its lobe's views share (the same glints, half vectors within a degree):
it is also scored with the simulator's true transmissions taken out (rig.simulators.world) and one shift for the
run, which takes out only what every point shares; and against the exact truth (rig.bench.truth.measured_exactly:
the BRDF at the axes' physical positions, the true transmissions out, one shift), where no fitted axis angle
takes anything from the errors the lobe's views share either. Last, each family and issue sample against the
exact truth, inside the issue's band (93–97 %, std(z) 0.85–1.15) or not.

    python benchmarks/measurement_coverage.py [--draws 10] [--seed 101] [--first 0] [--issue-seeds 4]
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

from rig.bench.draws import FAMILIES, Draw, draw  # noqa: E402
from rig.bench.error_vs_time import machine  # noqa: E402
from rig.bench.truth import measured_exactly  # noqa: E402
from rig.config.campaign import Campaign, SimulatedBrdf, load_campaign  # noqa: E402
from rig.config.rigfile import RigConfig, SimulationConfig, simulated_rig  # noqa: E402
from rig.physics.brdf_models import get_model  # noqa: E402
from rig.physics.geometry import AXIS_NAMES, directions_scs  # noqa: E402

CAMPAIGN = ROOT / "campaigns" / "spieringhs2023-rm1.yaml"
#: The issue's kinds of hidden sample, as the repository's test campaigns measure them.
ISSUE_SAMPLES = {"glossy n=3000 wheel": ROOT / "tests" / "campaigns" / "e2e-glossy.yaml",
                 "steep RetroPhong RM3": ROOT / "tests" / "campaigns" / "e2e-steep.yaml"}


def zero_error_columns(family: str, params: dict[str, float], motors_deg: np.ndarray,
                       step_deg: float = 0.01) -> np.ndarray:
    """(N, 4): d ln(f_true · cos θi)/d(axis angle) per degree at each point's axis positions (N, 4), one column
    per axis: what a zero error of that axis does to the measured f (the physical angle is the read-back plus
    it). On a diffuse sample only the stage's (tan θi); near a lobe every axis's, with the lobe's slope."""
    model = get_model(family)

    def log_signal(motors: np.ndarray) -> np.ndarray:
        wi, wo = directions_scs(*np.radians(motors.T))
        return np.log(np.maximum(model(wi, wo, params) * wi[..., 2], 1e-300))
    steps = np.eye(4) * step_deg
    return np.column_stack([(log_signal(motors_deg + d) - log_signal(motors_deg - d)) / (2 * step_deg)
                            for d in steps])


def shared_out(rel: np.ndarray, u_rel: np.ndarray, filter_position: np.ndarray,
               zero_columns: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """z of the relative errors once the run's shared errors are taken out, and each filter's shift: a weighted
    least-squares fit of one shift per filter position plus one angle per axis (its zero error, through
    `zero_error_columns`)."""
    positions = np.unique(filter_position)
    design = np.column_stack([(filter_position == p).astype(float) for p in positions] + [zero_columns])
    coef = np.linalg.lstsq(design / u_rel[:, None], rel / u_rel, rcond=None)[0]
    return (rel - design @ coef) / u_rel, coef[:len(positions)]


#: How the shared errors are taken out before z (`scores`): one shift per filter position and the axes' zero errors
#: through the truth's slope, fitted (what a lab could do); the simulator's true transmissions divided out and one
#: shift, the axes still fitted; the exact truth (rig.bench.truth.measured_exactly) and one shift, nothing else.
ANALYSES = ("fitted", "true T", "exact")


def point_errors(drawn: Draw, out: Path) -> dict[str, dict[str, np.ndarray]]:
    """Measure the drawn sample with the paper table on a simulated rig of its own: `scores`."""
    base = load_campaign(CAMPAIGN)
    sample = base.sample.model_copy(update={"simulated_brdf": SimulatedBrdf(model=drawn.family, params=drawn.params)})
    rig = simulated_rig().model_copy(update={"simulation": SimulationConfig(seed=drawn.seed * 1000 + drawn.index)})
    return scores(base.model_copy(update={"sample": sample}), rig, out)


def scores(campaign: Campaign, rig: RigConfig, out: Path) -> dict[str, dict[str, np.ndarray]]:
    """Measure `campaign` on the simulated `rig` once and score it by each of ANALYSES; per analysis and point: z of
    the point-to-point part (the shared errors taken out: `shared_out`), z against the whole u, the relative error,
    and per shift fitted the shift with the median correlated u of its points. Points the camera saturated
    (flagged) are left out."""
    d, exact = measured_exactly(campaign, rig, out)
    spec = campaign.sample.simulated_brdf
    assert spec is not None
    ok = ~d.has_flag("roi_saturated")
    nominal = get_model(spec.model)(*d.directions(), spec.params)[ok]
    f, u, position = d["brdf_per_sr"][ok], d["u_brdf_per_sr"][ok], d["filter_position"][ok]
    u_point_rel, u_corr_rel = d["u_brdf_point_per_sr"][ok] / f, d["u_brdf_correlated_per_sr"][ok] / f
    ratio, truth = exact.transmission_ratio[ok], exact.brdf_per_sr[ok]
    axes = zero_error_columns(spec.model, spec.params, np.column_stack([d[f"{a}_deg"][ok] for a in AXIS_NAMES]))
    one = np.zeros_like(position)
    setups = {"fitted": (f / nominal - 1, position, axes, nominal),
              "true T": (f / ratio / nominal - 1, one, axes, nominal),
              "exact": (f / ratio / truth - 1, one, axes[:, :0], truth)}
    out_scores = {}
    for how, (rel, groups, columns, reference) in setups.items():
        z_point, shifts = shared_out(rel, u_point_rel, groups, columns)
        out_scores[how] = {"z_point": z_point, "z_total": (f - reference) / u, "rel": rel, "shift": np.array(shifts),
                           "u_corr": np.array([np.median(u_corr_rel[groups == p]) for p in np.unique(groups)]),
                           "u_point_rel": u_point_rel}
    return out_scores


def pooled_line(name: str, runs: list[dict[str, np.ndarray]]) -> str:
    """`line` of several runs' points together."""
    return line(name, {key: np.concatenate([r[key] for r in runs]) for key in runs[0]})


def line(name: str, r: dict[str, np.ndarray]) -> str:
    z, zt = r["z_point"], r["z_total"]
    return (f"{name:22s} {z.size:5d} {np.mean(np.abs(z) <= 2):7.3f} {z.std():6.2f} {z.mean():+6.2f} "
            f"{np.median(r['u_point_rel']):8.4f} {np.median(np.abs(r['rel'])):8.4f} "
            f"{np.max(np.abs(r['shift'])):7.4f} {np.median(r['u_corr']):7.4f} "
            f"{np.mean(np.abs(zt) <= 2):7.3f} {zt.std():6.2f}")


#: The issue's band for the point-to-point part: k = 2 coverage and std(z).
BAND_COVERAGE, BAND_STD = (0.93, 0.97), (0.85, 1.15)


def verdict(name: str, runs: list[dict[str, np.ndarray]]) -> str:
    """Whether the pooled point-to-point z of `runs` lie inside the issue's band (BAND_COVERAGE, BAND_STD)."""
    z = np.concatenate([r["z_point"] for r in runs])
    cover, spread = float(np.mean(np.abs(z) <= 2)), float(z.std())
    inside = BAND_COVERAGE[0] <= cover <= BAND_COVERAGE[1] and BAND_STD[0] <= spread <= BAND_STD[1]
    return f"{name:22s} {100 * cover:5.1f} % / {spread:4.2f}  {'inside' if inside else 'OUTSIDE'}"


def issue_rig(seed: int) -> RigConfig:
    """The simulated rig (with its filter wheel) on `seed`."""
    return simulated_rig().model_copy(update={"simulation": SimulationConfig(seed=seed)})


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=10)
    parser.add_argument("--seed", type=int, default=101)
    parser.add_argument("--first", type=int, default=0, help="index of the first draw")
    parser.add_argument("--issue-seeds", type=int, default=4, help="simulated rigs per issue sample (0: none)")
    args = parser.parse_args()
    print(machine())
    print(f"draws {args.first}…{args.first + args.draws - 1} of seed {args.seed} (rig.bench.draws), each measured "
          f"with {CAMPAIGN.name}'s table on its own simulated rig; z of the point-to-point part (shared errors out)")
    head = (f"{'draw':22s} {'n':>5s} {'cov k=2':>7s} {'std z':>6s} {'mean z':>6s} {'med u_pt':>8s} {'med|rel|':>8s} "
            f"{'max|sh|':>7s} {'u_corr':>7s} {'cov tot':>7s} {'std zt':>6s}")
    print(head)
    pooled: dict[tuple[str, str], list[dict[str, np.ndarray]]] = {}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.first, args.first + args.draws):
            drawn = draw(args.seed, k)
            r = point_errors(drawn, Path(tmp) / f"draw{k}")
            for how in ANALYSES:
                pooled.setdefault((drawn.family, how), []).append(r[how])
            print(line(drawn.name, r["fitted"]), flush=True)
    for how in ("fitted", "exact"):
        print(f"per family (draws pooled), shared errors {how}:")
        print(head)
        for family in FAMILIES:
            if (family, how) in pooled:
                print(pooled_line(family, pooled[(family, how)]))
    if args.issue_seeds:
        print(f"the issue's kinds of sample, {args.issue_seeds} simulated rigs each "
              f"(seeds {args.seed}·1000 + 500 + k):")
        print(head)
    exact = [(family, pooled[(family, "exact")]) for family in FAMILIES if (family, "exact") in pooled]
    with tempfile.TemporaryDirectory() as tmp:
        for name, path in ISSUE_SAMPLES.items():
            runs = [scores(load_campaign(path), issue_rig(args.seed * 1000 + 500 + k), Path(tmp) / f"{path.stem}-{k}")
                    for k in range(args.issue_seeds)]
            for how in ANALYSES if runs else ():
                print(pooled_line(f"{name[:14]} {how}", [r[how] for r in runs]), flush=True)
            exact += [(name[:14], [r["exact"] for r in runs])] if runs else []
    print(f"against the exact truth, the issue's band ({100 * BAND_COVERAGE[0]:.0f}–{100 * BAND_COVERAGE[1]:.0f} %, "
          f"std(z) {BAND_STD[0]}–{BAND_STD[1]}):")
    for name, runs in exact:
        print(verdict(name, runs))
    print(f"wall time {time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
