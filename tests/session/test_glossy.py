"""Extreme cases on the simulated rig with its neutral-density filter wheel: a glossy lobe (modified Phong
n = 3000, peak 382 sr⁻¹) at three incidences, a mirror-like one (n = 30000, lobe narrower than the ROI's
angular footprint) and a near-black diffuse sample (kd = 0.01).

The glossy sample saturates the camera at its shortest exposure over a wide part of its lobe: without the
wheel about half its points are lower bounds; with it none is. Its campaign aligns the arm on the sample's
specular peak first (without it the axes' zero errors, through the lobe's slope, leave the median error at
about 1 %: benchmarks/glossy.py); then the median error is below 1 % and k = 2 coverage holds, pooled over
independent simulated rigs (seeds) because the axis errors are shared by a run's points. A filter's transmission
error (drawn by the simulator within its certificate's u, `u_rel_attenuation`) is one error of every point through
it, so that three rigs make three draws of it: the coverage is of the rest of u, the filters' true transmissions
divided out (a rig whose ND 1 draws 2.2 σ otherwise puts half its lobe beyond k = 2 at once).
"""

import csv
import json

import numpy as np
import pytest

from repo_paths import TEST_CAMPAIGNS
from rig.acquisition.run import run_campaign
from rig.config.campaign import Campaign, load_campaign
from rig.config.rigfile import RigConfig, SimulationConfig, simulated_rig
from rig.data.dataset_reader import load
from rig.physics.brdf_models import get_model
from rig.session.connect import open_campaign_rig
from rig.simulators.world import SimWorld

GLOSSY = load_campaign(TEST_CAMPAIGNS / "e2e-glossy.yaml")
SEEDS = (1, 2, 3)


def with_sample(campaign: Campaign, model: str, params: dict[str, float]) -> Campaign:
    truth = campaign.sample.simulated_brdf
    return campaign.model_copy(update={"sample": campaign.sample.model_copy(update={
        "simulated_brdf": truth.model_copy(update={"model": model, "params": params})})})


def measured(tmp_path, campaign: Campaign, rig: RigConfig, seed: int):
    rig = rig.model_copy(update={"simulation": SimulationConfig(seed=seed)})
    out = tmp_path / f"{campaign.sample.simulated_brdf.model}-{seed}"
    outcome = run_campaign(campaign, rig, out, open_campaign_rig)
    assert outcome.status == "complete"
    d = load(out)
    spec = campaign.sample.simulated_brdf
    truth = get_model(spec.model)(*d.directions(), spec.params)
    with (out / "brdf.csv").open() as f:
        rows = list(csv.DictReader(f))
    world = SimWorld(rig, get_model(spec.model), spec.params)
    certified = {flt.position: flt.transmission for flt in rig.attenuator.filters} if rig.attenuator else {}
    off = np.array([world.transmission_truth.get(p, 1.0) / certified.get(p, 1.0) for p in d["filter_position"]])
    return d["brdf_per_sr"], d["u_brdf_per_sr"], truth, rows, off


@pytest.fixture(scope="module")
def glossy(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("glossy")
    return [measured(tmp, GLOSSY, simulated_rig(), seed) for seed in SEEDS]


def test_glossy_lobe_through_the_wheel_has_no_lower_bound_and_honest_uncertainty(glossy):
    f = np.concatenate([g[0] for g in glossy])
    u = np.concatenate([g[1] for g in glossy])
    truth = np.concatenate([g[2] for g in glossy])
    rows = [r for g in glossy for r in g[3]]
    assert not any("roi_saturated" in r["flags"] for r in rows)
    assert {int(r["filter_position"]) for r in rows} >= {1, 2, 3}          # open on the base, ND 1–2 on the lobe
    assert all(float(r["u_rel_attenuation"]) > 0 for r in rows if int(r["filter_position"]) > 1)
    rel = np.abs(f / truth - 1)
    assert np.median(rel) <= 0.01, f"median |relative error| {np.median(rel):.4f}"
    off = np.concatenate([g[4] for g in glossy])                          # true transmission / certificate's
    u_att = np.array([float(r["u_rel_attenuation"]) for r in rows]) * f
    z = (f / off - truth) / np.sqrt(u ** 2 - u_att ** 2)
    # 0.943 over these 3 seeds: the lower bound keeps a point of margin for machines whose floating point differs,
    # so that the test guards the budget without being flaky
    assert 0.92 <= np.mean(np.abs(z) <= 2) <= 0.97, f"k=2 coverage {np.mean(np.abs(z) <= 2):.3f}"
    flank = (truth > 1.0) & (truth < 300.0)                                 # on the lobe, off its peak
    assert flank.sum() > 100 and np.mean(np.abs(z[flank]) <= 2) >= 0.9
    assert any(float(r["lobe_bias_rel"]) != 0 for r in rows)                # the footprint is accounted for


def test_without_the_wheel_the_glossy_peak_is_a_lower_bound(tmp_path):
    unaligned = GLOSSY.model_copy(update={"alignment": None})         # its scan would saturate the camera
    _, _, _, rows, _ = measured(tmp_path, unaligned, RigConfig(), SEEDS[0])
    saturated = [r for r in rows if "roi_saturated" in r["flags"]]
    assert len(saturated) > len(rows) // 4 and all(int(r["filter_position"]) == 0 for r in rows)


def test_a_mirror_like_lobe_is_flagged_narrower_than_the_footprint(tmp_path):
    mirror = with_sample(GLOSSY, "modified_phong", {"kd": 0.05, "ks": 0.8, "n": 30000.0})   # peak 3.8e3 sr⁻¹
    f, u, truth, rows, _ = measured(tmp_path, mirror, simulated_rig(), SEEDS[0])
    assert not any("roi_saturated" in r["flags"] for r in rows)
    assert max(int(r["filter_position"]) for r in rows) >= 3
    narrow = ["narrow_lobe" in r["flags"] for r in rows]
    assert any(narrow)
    dataset = json.loads((tmp_path / f"modified_phong-{SEEDS[0]}" / "dataset.json").read_text())
    assert dataset["alignment"]["lobe_width_deg"] < 0.5                     # aligned on its own narrow peak
    manifest = dataset["footprint"]
    assert manifest["narrow_lobe_points"] == sum(narrow) and manifest["view_half_angle_deg"] > 0.3
    peak = np.argmax(truth)
    assert narrow[peak] and abs(f[peak] / truth[peak] - 1) <= 2 * u[peak] / truth[peak] + 0.05


def test_a_near_black_sample_is_measured_without_filters(tmp_path):
    black = with_sample(load_campaign(TEST_CAMPAIGNS / "e2e-reduced.yaml"), "lambert", {"kd": 0.01})
    f, u, truth, rows, _ = measured(tmp_path, black, simulated_rig(), SEEDS[0])
    assert all(int(r["filter_position"]) == 1 for r in rows)
    assert not any("low_signal" in r["flags"] or "roi_saturated" in r["flags"] for r in rows)
    assert np.median(np.abs(f / truth - 1)) <= 0.01 and np.mean(np.abs(f - truth) <= 2 * u) >= 0.85
