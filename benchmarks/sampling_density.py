"""Benchmark: what sets the table's in-hull p95 — the spacing of its incidences or of its viewing rings (issue 33).

A dry study: no simulated rig, rows synthesised from the drawn sample's truth at the planned angles with 0.3 %
noise (a point's own u), one per isotropic pair. Per drawn sample (rig.bench.draws) it scores, with the
interpolant of `rig predict` inside the table's measured domain (as `rig bench sampling` does):

- the table (its views at its incidences);
- the table's views at every candidate incidence (the θi range filled at 5°);
- the table's incidences with the rings between its patterns' rings added (rig.planning.candidates.between_rings);
- both.

    python benchmarks/sampling_density.py [CAMPAIGN] [--draws 5] [--seed 7]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.analysis.adaptive import rows_dataset  # noqa: E402
from rig.analysis.held_out import interpolating_predictor  # noqa: E402
from rig.analysis.predict import InterpolatingPredictor, measured_domain  # noqa: E402
from rig.analysis.validation import TruthPredictor, representation_error, validation_set  # noqa: E402
from rig.bench.draws import Draw, draws  # noqa: E402
from rig.bench.error_vs_time import machine  # noqa: E402
from rig.bench.sampling import domain_of  # noqa: E402
from rig.config.campaign import Campaign, IncidenceSeries, load_campaign  # noqa: E402
from rig.config.rigfile import RigConfig  # noqa: E402
from rig.data.dataset_reader import Dataset  # noqa: E402
from rig.planning.candidates import between_rings, filled_thetas, one_per_isotropic_pair  # noqa: E402
from rig.planning.points import PlannedPoint  # noqa: E402
from rig.planning.table import table_plan  # noqa: E402

NOISE_REL = 0.003


def synthesised(points: list[PlannedPoint], drawn: Draw) -> Dataset:
    """Rows from the truth at the planned angles, with NOISE_REL relative noise (seeded by the draw)."""
    truth = TruthPredictor(drawn.family, drawn.params)
    a = np.array([(p.theta_i_deg, p.phi_i_deg, p.theta_o_deg, p.phi_o_deg) for p in points])
    rng = np.random.default_rng([drawn.seed, drawn.index])
    f = truth.predict(*a.T).brdf_per_sr * (1 + NOISE_REL * rng.standard_normal(len(a)))
    rows = [{"point_id": p.point_id, "brdf_per_sr": v, "u_brdf_per_sr": NOISE_REL * v} for p, v in zip(points, f)]
    return rows_dataset(rows, {p.point_id: p for p in points})


def variants(campaign: Campaign, rig: RigConfig) -> dict[str, list[PlannedPoint]]:
    filled = [IncidenceSeries(phi=e.phi, theta=filled_thetas(e.theta)) for e in campaign.incidence]
    rings = list(campaign.viewing) + between_rings(campaign.viewing)
    out = {}
    for name, update in (("table", {}), ("θi at 5°", {"incidence": filled}), ("rings between", {"viewing": rings}),
                         ("both", {"incidence": filled, "viewing": rings})):
        out[name] = one_per_isotropic_pair(table_plan(campaign.model_copy(update=update), rig).points)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("campaign", nargs="?", default=str(ROOT / "campaigns" / "spieringhs2023-rm1.yaml"))
    parser.add_argument("--draws", type=int, default=5)
    parser.add_argument("--seed", type=int, default=7)
    args = parser.parse_args()
    campaign, rig = load_campaign(Path(args.campaign)), RigConfig()
    sets = variants(campaign, rig)
    domain = domain_of(campaign, rig)
    print(machine())
    print(f"{Path(args.campaign).name}; in-hull p95 of rows synthesised at the planned angles ({NOISE_REL:.1%} noise)")
    print(f"{'draw':18s}" + "".join(f"{f'{name} ({len(pts)})':>22s}" for name, pts in sets.items()))
    for drawn in draws(args.seed, args.draws):
        truth = TruthPredictor(drawn.family, drawn.params)
        reference = InterpolatingPredictor(measured_domain(synthesised(sets["table"], drawn)))
        line = f"{drawn.name:18s}"
        for points in sets.values():
            ds = synthesised(points, drawn)
            measured = np.stack([ds[c] for c in ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg")], axis=1)
            vset = validation_set(domain, seed=drawn.seed * 1000 + drawn.index, measured_deg=measured)
            err = representation_error(interpolating_predictor(ds), truth, vset, domain, road=False,
                                       reference=reference)
            line += f"{err.row()['all_p95']:22.4f}"
        print(line, flush=True)


if __name__ == "__main__":
    main()
