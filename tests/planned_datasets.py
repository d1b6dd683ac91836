"""Closed-form datasets on a campaign's planned directions, without a simulated run: the plan's (θi, φi, θo, φo) with
a known BRDF's values, for tests of what stands on a dataset (prediction, validation, exports)."""

from pathlib import Path

import numpy as np

from repo_paths import CAMPAIGNS
from rig.analysis.validation import TruthPredictor
from rig.config.campaign import load_campaign
from rig.config.rigfile import simulated_rig
from rig.data.dataset_reader import Dataset
from rig.planning.plan import build_plan

#: RetroPhong RM1 of Spieringhs et al. 2023, Table 7 (the paper campaign's simulated sample).
RM1 = {"kd": 0.620, "n": 24.0, "k1": 0.158, "k2": 0.0415, "k3": 0.00133, "k4": 5.47}


def planned_dataset(drop=lambda ti, to, po: np.zeros(ti.shape, bool), path=CAMPAIGNS / "spieringhs2023-rm1.yaml",
                    noise_rel: float = 0.0, model: str = "retrophong", params: dict | None = None) -> Dataset:
    """A campaign's planned directions (the paper's by default) with a closed-form BRDF's values (RM1's by default;
    times 1 + noise_rel·N(0, 1), seeded) and a 0.3 % u, less the `drop`ped."""
    campaign, rig = load_campaign(path), simulated_rig()
    pts = build_plan(campaign, rig).points
    a = np.array([(p.theta_i_deg, p.phi_i_deg, p.theta_o_deg, p.phi_o_deg, p.series) for p in pts])
    a = a[~drop(a[:, 0], a[:, 2], a[:, 3] - a[:, 1])]
    a, series = a[:, :4], a[:, 4]
    f = TruthPredictor(model, RM1 if params is None else params).predict(*a.T).brdf_per_sr
    f = f * (1 + noise_rel * np.random.default_rng(0).standard_normal(f.shape))
    columns = {"theta_i_deg": a[:, 0], "phi_i_deg": a[:, 1], "theta_o_deg": a[:, 2], "phi_o_deg": a[:, 3],
               "brdf_per_sr": f, "u_brdf_per_sr": 0.003 * f, "series": series}
    n = len(f)
    return Dataset(path=Path("mem"), manifest={}, columns=columns, point_id=[f"p{k}" for k in range(n)],
                   flags=[()] * n, time_utc=[""] * n, skipped=[], header=tuple(columns))
