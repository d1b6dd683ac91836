"""How close the albedo of a Zemax export *from data* comes to the simulated truth, and why (issue 37).

    python benchmarks/zemax_albedo.py [CAMPAIGN.yaml ...]

For each campaign (default: the reduced end-to-end one and the paper's Table 1 × Table 2), measured on the
simulated rig: the directional albedo ∫ f cos θo dω at a few incidences of

- the truth (the campaign's simulated BRDF) on the export's own grid: the grid's share of the error;
- the export (`rig export --format zemax --source data`, the reconstruction of `rig predict`), split into the
  directions the reconstruction interpolates (inside the measured views' hull) and those where it extrapolates.

The split says where an albedo error comes from: directions the campaign never looked at (extrapolated), or the
interpolation between views too far apart where a lobe's tail meets the diffuse floor (inside). docs/zemax.md
quotes the output.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.analysis.held_out import interpolating_predictor  # noqa: E402
from rig.cli.main import main  # noqa: E402
from rig.config.campaign import load_campaign  # noqa: E402
from rig.data.dataset_reader import load  # noqa: E402
from rig.data.zemax import FormulaPredictor, grid_for, scatter_directions, table_albedo  # noqa: E402

CAMPAIGNS = [ROOT / "tests" / "campaigns" / "e2e-reduced.yaml", ROOT / "campaigns" / "spieringhs2023-rm1.yaml"]
INCIDENCES_DEG = (0.0, 20.0, 40.0, 60.0, 80.0, 85.0)


def report(campaign_path: Path, tmp: Path) -> None:
    out = tmp / campaign_path.stem
    assert main(["run", str(campaign_path), "--out", str(out), "--quiet"]) == 0
    ds = load(out)
    truth_spec = load_campaign(campaign_path).sample.simulated_brdf
    truth = FormulaPredictor(truth_spec.model, dict(truth_spec.params))
    predictor = interpolating_predictor(ds)
    grid = grid_for(predictor, float(np.round(np.max(ds["theta_i_deg"]), 1)))
    print(f"\n{campaign_path.name}: {len(ds)} points; albedo at θi (truth, export from data, relative error; "
          "error inside the measured hull | where extrapolated, as shares of the truth; extrapolated share of the "
          "truth's albedo)")
    for theta_i in INCIDENCES_DEG:
        wo = scatter_directions(theta_i, grid.azimuth_deg, grid.radial_deg)
        above = wo[..., 2] > 1e-9
        theta_o = np.where(above, np.degrees(np.arccos(np.clip(wo[..., 2], -1, 1))), 0.0)
        phi_o = np.degrees(np.arctan2(wo[..., 1], wo[..., 0]))
        p = predictor.predict(theta_i, 0.0, theta_o, phi_o)
        f, beyond = np.where(above, p.brdf_per_sr, 0.0), np.asarray(p.extrapolated) & above
        f_true = np.where(above, truth.predict(theta_i, 0.0, theta_o, phi_o).brdf_per_sr, 0.0)
        a, a_true = table_albedo(f, theta_i, grid), table_albedo(f_true, theta_i, grid)
        err_beyond = table_albedo(np.where(beyond, f - f_true, 0.0), theta_i, grid)
        share_beyond = table_albedo(np.where(beyond, f_true, 0.0), theta_i, grid) / a_true
        print(f"  θi {theta_i:4.0f}°: truth {a_true:.4f}  export {a:.4f}  {100 * (a / a_true - 1):+6.2f} %   "
              f"inside {100 * (a - a_true - err_beyond) / a_true:+6.2f} % | beyond {100 * err_beyond / a_true:+6.2f} %"
              f"   extrapolated share {100 * share_beyond:4.0f} %")


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as tmp:
        for path in [Path(a) for a in sys.argv[1:]] or CAMPAIGNS:
            report(path, Path(tmp))
