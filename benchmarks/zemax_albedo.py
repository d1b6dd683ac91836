"""How close the albedo of a Zemax export *from data* comes to the simulated truth, and why (issue 37).

    python benchmarks/zemax_albedo.py [--draws 2] [--seed 101] [--first 0] [--sim-seed 1] [--campaign C.yaml ...]

Each campaign (default: the paper's Table 1 × Table 2, campaigns/spieringhs2023-rm1.yaml) is measured on the simulated
rig with its own sample (the paper's RM1) and with `--draws` samples of rig.bench.draws (families in turn:
RetroPhong, MRM + diffuse, …; each on a rig of its own seed). At every incidence the campaign measured, the directional
albedo ∫ f cos θo dω of

- the truth (the simulated BRDF) on the export's own grid (its error against the closed form: the grid's share);
- the export from data as `rig predict`'s piecewise-linear reconstruction gives it (the export before issue 37's fix);
- the export from data as `rig export --format zemax --source data` writes it (rig.analysis.smooth_views: a C¹ cubic
  within each incidence), split into the error inside the measured views' hull (interpolated) and beyond it
  (held at the hull's edge), and the share of the truth's albedo that lies beyond;
- the same two reconstructions from the closed-form values at the measured views (no measurement error): what the
  interpolant alone does.

docs/zemax.md quotes the output.
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
from rig.analysis.smooth_views import smooth_predictor  # noqa: E402
from rig.bench.draws import draw  # noqa: E402
from rig.bench.error_vs_time import machine  # noqa: E402
from rig.config.campaign import Campaign, SimulatedBrdf, load_campaign  # noqa: E402
from rig.config.rigfile import SimulationConfig, simulated_rig  # noqa: E402
from rig.data.dataset_reader import Dataset, load  # noqa: E402
from rig.data.zemax import FormulaPredictor, Predictor, grid_for, scatter_directions, table_albedo  # noqa: E402
from rig.physics.brdf_models import albedo, get_model  # noqa: E402
from rig.session.connect import open_campaign_rig  # noqa: E402

PAPER = ROOT / "campaigns" / "spieringhs2023-rm1.yaml"


def measured(campaign: Campaign, sim_seed: int, out: Path) -> Dataset:
    outcome = run_campaign(campaign, simulated_rig().model_copy(update={"simulation": SimulationConfig(seed=sim_seed)}),
                           out, open_campaign_rig)
    if outcome.status != "complete":
        raise RuntimeError(f"{campaign.name}: run {outcome.status}: {outcome.error}")
    return load(out)


def with_exact_values(ds: Dataset, truth: SimulatedBrdf) -> Dataset:
    """`ds` with the closed-form BRDF at its achieved angles in place of the measured values."""
    wi, wo = ds.directions()
    return Dataset(**{**ds.__dict__, "columns": {**ds.columns, "brdf_per_sr": get_model(truth.model)(
        wi, wo, dict(truth.params))}})


def errors(predictor: Predictor, truth: FormulaPredictor, theta_i: float, grid) -> tuple[float, float, float, float]:
    """(truth's albedo on the grid, relative error, error beyond the hull, truth's share beyond the hull)."""
    wo = scatter_directions(theta_i, grid.azimuth_deg, grid.radial_deg)
    above = wo[..., 2] > 1e-9
    theta_o = np.where(above, np.degrees(np.arccos(np.clip(wo[..., 2], -1, 1))), 0.0)
    phi_o = np.degrees(np.arctan2(wo[..., 1], wo[..., 0]))
    p = predictor.predict(theta_i, 0.0, theta_o, phi_o)
    f, beyond = np.where(above, p.brdf_per_sr, 0.0), np.asarray(p.extrapolated) & above
    f_true = np.where(above, truth.predict(theta_i, 0.0, theta_o, phi_o).brdf_per_sr, 0.0)
    a_true = table_albedo(f_true, theta_i, grid)
    return (a_true, table_albedo(f, theta_i, grid) / a_true - 1,
            table_albedo(np.where(beyond, f - f_true, 0.0), theta_i, grid) / a_true,
            table_albedo(np.where(beyond, f_true, 0.0), theta_i, grid) / a_true)


def report(name: str, campaign: Campaign, sim_seed: int, tmp: Path) -> float:
    """Print one campaign × sample; the largest |albedo error| of the export (as written now) over its incidences."""
    spec = campaign.sample.simulated_brdf
    assert spec is not None
    t0 = time.perf_counter()
    ds = measured(campaign, sim_seed, tmp / name)
    truth = FormulaPredictor(spec.model, dict(spec.params))
    exact = with_exact_values(ds, spec)
    linear, smooth = interpolating_predictor(ds), smooth_predictor(ds)
    linear_exact, smooth_exact = interpolating_predictor(exact), smooth_predictor(exact)
    grid = grid_for(smooth, float(np.round(np.max(ds["theta_i_deg"]), 1)))
    print(f"\n{name}: {spec.model} {', '.join(f'{k} {v:.3g}' for k, v in spec.params.items())}; {campaign.name}, "
          f"{len(ds)} points, simulation seed {sim_seed}; grid {len(grid.incidence_deg)} rows × "
          f"{len(grid.azimuth_deg)} × {len(grid.radial_deg)}")
    print("   θi   truth  grid | linear  C1 cubic (inside | beyond)  share beyond | exact values: linear  C1 cubic")
    worst = 0.0
    model = get_model(spec.model)
    for theta_i in np.round(smooth.domain.theta_i_deg, 1):
        a, old, _, _ = errors(linear, truth, theta_i, grid)
        _, new, new_beyond, share = errors(smooth, truth, theta_i, grid)
        old_exact, new_exact = errors(linear_exact, truth, theta_i, grid)[1], errors(smooth_exact, truth, theta_i,
                                                                                         grid)[1]
        on_grid = a / float(albedo(model, dict(spec.params), theta_i)) - 1
        worst = max(worst, abs(new))
        print(f"  {theta_i:4.0f}° {a:.4f} {100 * on_grid:+5.2f} | {100 * old:+6.2f} {100 * new:+6.2f} % "
              f"({100 * (new - new_beyond):+5.2f} | {100 * new_beyond:+5.2f})  {100 * share:4.0f} %       | "
              f"{100 * old_exact:+6.2f} {100 * new_exact:+6.2f} %")
    print(f"  worst |albedo error| of the export: {100 * worst:.2f} % ({time.perf_counter() - t0:.0f} s)")
    return worst


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--draws", type=int, default=2, help="samples of rig.bench.draws beside the campaign's own")
    parser.add_argument("--seed", type=int, default=101, help="the draws' study seed")
    parser.add_argument("--first", type=int, default=0, help="index of the first draw")
    parser.add_argument("--sim-seed", type=int, default=1, help="the simulated rig's seed for the campaign's sample")
    parser.add_argument("--campaign", action="append", type=Path, help=f"campaign file(s) (default {PAPER.name})")
    args = parser.parse_args()
    print(machine())
    print(f"settings: campaigns {', '.join(p.name for p in args.campaign or [PAPER])}; draws {args.first}…"
          f"{args.first + args.draws - 1} of seed {args.seed} (rig.bench.draws, each on a rig seeded "
          f"seed·1000 + index); albedo errors relative to the truth's on the export's grid")
    worst = []
    with tempfile.TemporaryDirectory() as tmp:
        for path in args.campaign or [PAPER]:
            base = load_campaign(path)
            worst.append(report(f"{path.stem} (own sample)", base, args.sim_seed, Path(tmp)))
            for k in range(args.first, args.first + args.draws):
                drawn = draw(args.seed, k)
                sample = base.sample.model_copy(update={"simulated_brdf": SimulatedBrdf(model=drawn.family,
                                                                                         params=drawn.params)})
                worst.append(report(f"{path.stem} × {drawn.name}", base.model_copy(update={"sample": sample}),
                                    drawn.seed * 1000 + drawn.index, Path(tmp)))
    print(f"\nworst |albedo error| over all: {100 * max(worst):.2f} %")


if __name__ == "__main__":
    main()
