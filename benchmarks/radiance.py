"""Benchmark: Radiance tensor-tree XMLs of the paper campaign against the simulated ground truth.

The paper campaign (campaigns/spieringhs2023-rm1.yaml, RetroPhong RM1 on the simulated rig) is measured
once, then exported to a tensor-tree BSDF XML three ways: from the measured data with one pab-opto file
per series as measured (`isotropic=False`: the φi = 23°, 45° series at θi ≥ 70° make pabopto2bsdf assume
quadrilateral symmetry), from the measured data turned to φi = 0 and merged per incidence
(`isotropic=True`), and from the RetroPhong fit of the dataset through a `.cal` of the model. Each XML
is evaluated back (pyradiance) at the measured directions with θi ≤ 85° and compared with the truth
(`campaign.sample.simulated_brdf`): median and p95 of |f_xml / f_true − 1|, and the time to build it.

    python benchmarks/radiance.py [--resolution N] [--cull PCT] [--campaign FILE]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
import warnings
from collections.abc import Callable
from functools import partial
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.acquisition.run import run_campaign  # noqa: E402
from rig.analysis.fit import fit_dataset  # noqa: E402
from rig.bench.error_vs_time import machine  # noqa: E402
from rig.config.campaign import load_campaign  # noqa: E402
from rig.config.rigfile import simulated_rig  # noqa: E402
from rig.data.dataset_reader import Dataset, load  # noqa: E402
from rig.data.radiance import PERCENT_CULL, RESOLUTION_LOG2, evaluate_xml, export_radiance_xml  # noqa: E402
from rig.physics.brdf_models import get_model  # noqa: E402
from rig.session.connect import open_campaign_rig  # noqa: E402

MAX_THETA_I_DEG = 85.0 + 0.5      # the paper's last incidence, achieved angles scatter by ~0.01°


def measure(campaign_file: Path, out: Path) -> tuple[Dataset, np.ndarray]:
    campaign, rig = load_campaign(campaign_file), simulated_rig()
    outcome = run_campaign(campaign, rig, out, open_campaign_rig)
    assert outcome.status == "complete", outcome.status
    ds = load(out)
    truth = campaign.sample.simulated_brdf
    assert truth is not None
    return ds, get_model(truth.model)(*ds.directions(), truth.params)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--campaign", type=Path, default=ROOT / "campaigns" / "spieringhs2023-rm1.yaml")
    ap.add_argument("--resolution", type=int, default=RESOLUTION_LOG2, help="bsdf2ttree -g (log2 resolution)")
    ap.add_argument("--cull", type=float, default=PERCENT_CULL, help="bsdf2ttree -t (percent culled, -1: none)")
    args = ap.parse_args()
    print(f"machine: {machine()}")
    print(f"settings: campaign {args.campaign.name}, bsdf2ttree -g {args.resolution} -t {args.cull:g}, "
          f"points with θi ≤ {MAX_THETA_I_DEG:g}°")
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        ds, truth = measure(args.campaign, Path(tmp) / "ds")
        print(f"measured {len(ds)} points in {time.perf_counter() - t0:.1f} s wall")
        t0 = time.perf_counter()
        fit = fit_dataset(ds, "retrophong")
        print(f"retrophong fit in {time.perf_counter() - t0:.1f} s: "
              + ", ".join(f"{k}={v:.4g}" for k, v in fit.params.items()))
        keep = ds["theta_i_deg"] <= MAX_THETA_I_DEG
        tree = {"resolution_log2": args.resolution, "percent_cull": args.cull}
        ways: dict[str, Callable[[Path], list[Path]]] = {
            "data, per series (before)": partial(export_radiance_xml, ds, source="data", isotropic=False, **tree),
            "data, turned to φi=0 + merged": partial(export_radiance_xml, ds, source="data", isotropic=True, **tree),
            "fitted retrophong .cal": partial(export_radiance_xml, ds, source="model", fit=fit.to_json(), **tree)}
        print(f"{'XML from':<32}{'median':>9}{'p95':>9}{'build s':>9}")
        for k, (name, write) in enumerate(ways.items()):
            xml = Path(tmp) / f"way{k}.xml"
            t0 = time.perf_counter()
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                write(xml)
            built = time.perf_counter() - t0
            f_xml = evaluate_xml(xml, *(ds[c][keep] for c in ("theta_i_deg", "phi_i_deg", "theta_o_deg",
                                                               "phi_o_deg")))
            rel = np.abs(f_xml / truth[keep] - 1.0)
            print(f"{name:<32}{np.median(rel):>9.1%}{np.percentile(rel, 95):>9.1%}{built:>9.1f}")
            for w in caught:
                print(f"    warning: {w.message}")


if __name__ == "__main__":
    main()
