"""Extreme and stiff cases on the simulated rig: grazing incidence, grazing views, poles, φ wrap,
lobes sharper than any exposure, a near-black sample, a huge dynamic range inside one ROI.

Every dataset column must stay finite, and every such case must be flagged, not hidden.
"""

import math

import numpy as np
import pytest

from rig.acquisition.run import prepare_run
from rig.config.campaign import parse_campaign
from rig.config.rigfile import RigConfig
from rig.data.dataset_format import BRDF_COLUMNS
from rig.data.dataset_reader import load
from rig.physics.brdf_models import get_model
from rig.planning.plan import build_plan
from rig.session.connect import open_campaign_rig

RM1 = {"kd": 0.620, "n": 24.0, "k1": 0.158, "k2": 0.0415, "k3": 0.00133, "k4": 5.47}


def measure(tmp_path, incidence, viewing, model="retrophong", params=RM1, **extra):
    campaign = parse_campaign({
        "name": "extreme", "sample": {"id": "x", "simulated_brdf": {"model": model, "params": params}},
        "incidence": incidence, "viewing": viewing, "lamp": {"warmup_min_s": 60}, **extra})
    rig = RigConfig()
    run = prepare_run(campaign, rig, tmp_path / "ds")
    outcome = run.run(open_campaign_rig)
    assert outcome.status == "complete", outcome.error
    return load(tmp_path / "ds"), run.plan


def assert_all_finite(d):
    for name in BRDF_COLUMNS:
        if name in d.columns and name != "exposures_s":
            assert np.all(np.isfinite(d[name])), name
    assert all(all(math.isfinite(t) and t > 0 for t in ts) for ts in d.columns["exposures_s"])


@pytest.mark.parametrize("theta_i", [85.0, 89.0, 89.9])
def test_grazing_incidence_is_flagged_and_finite(tmp_path, theta_i):
    d, _ = measure(tmp_path, [{"phi": 0, "theta": [theta_i]}], [{"points": [[30, 0], [50, 180], [20, 90]]}],
                   limits={"grazing_limit_deg": 88.0})
    assert len(d) == 3
    assert_all_finite(d)
    assert np.all(d.has_flag("grazing_incidence") == (d["theta_i_deg"] >= 88.0))
    # the angle term dominates the budget as cos θi → 0 (tan θi · u_θ: 2 % per 0.1° at 85°)
    # split into the read-back (point to point) and the axes' fixed zero errors (common to the campaign)
    geometry = RigConfig().geometry
    u_angle = np.tan(np.radians(d["theta_i_deg"])) * np.radians(geometry.angle_u_deg)
    u_readback = np.tan(np.radians(d["theta_i_deg"])) * np.radians(geometry.readback_u_deg)
    np.testing.assert_allclose(d["u_rel_angle"], u_readback, rtol=1e-9)
    np.testing.assert_allclose(np.hypot(d["u_rel_angle"], d["u_rel_angle_zero"]), u_angle, rtol=1e-9)
    assert np.all(d["u_brdf_per_sr"] / d["brdf_per_sr"] >= u_angle)


def test_grazing_views_leave_the_spot(tmp_path):
    campaign = parse_campaign({
        "name": "x", "sample": {"id": "x", "simulated_brdf": {"model": "lambert", "params": {"kd": 0.5}}},
        "incidence": [{"phi": 0, "theta": [0]}], "viewing": [{"points": [[60, 0], [80, 0], [84, 90], [89, 0]]}]})
    plan = build_plan(campaign, RigConfig())
    assert [s.reason for s in plan.skipped] == ["roi_unlit", "roi_unlit", "beyond_max_view_theta"]
    d, _ = measure(tmp_path, [{"phi": 0, "theta": [0]}], [{"points": [[60, 0], [80, 0], [84, 90]]}],
                   model="lambert", params={"kd": 0.5}, limits={"skip_roi_unlit": False})
    assert_all_finite(d)
    order = np.argsort(d["theta_o_deg"])                   # 60°, 80°, 84° whatever the travel order
    assert list(d.has_flag("roi_unlit")[order]) == [False, True, True]
    # a half-lit ROI is not the sample's value (its mean reads low; a lobe fit of the spot's edge does not
    # rescue it): the flag is what keeps it out of fits
    f = d["brdf_per_sr"][order]
    assert abs(f[1] / (0.5 / np.pi) - 1) > 0.03 and f[2] < 0.97 * 0.5 / np.pi


def test_poles_and_phi_wrap(tmp_path):
    """Azimuths next to the wrap (φ = 360 itself is refused by the campaign schema: φ in [0, 360))."""
    d, plan = measure(tmp_path, [{"phi": 0, "theta": [0, 30]}, {"phi": 359.9999, "theta": [30]}],
                      [{"points": [[0, 123.0], [20, 0], [20, 359.9999]]}],
                      model="lambert", params={"kd": 0.5})
    assert len(plan.series) == 3
    assert_all_finite(d)
    assert np.all((d["phi_o_deg"] >= 0) & (d["phi_o_deg"] < 360))
    # the pole view at θi = 0 is the occluded retro direction; at θi = 30° it is measured in both series
    assert len(d) == 8 and [s.reason for s in plan.skipped] == ["occluded_by_lamp"]
    at_pole = d["theta_o_deg"] < 0.01       # within encoder resolution of the pole: φo finite, whatever it is
    assert at_pole.sum() == 2
    np.testing.assert_allclose(d["brdf_per_sr"], 0.5 / np.pi, rtol=0.03)


def test_steep_retro_lobe_n68(tmp_path):
    d, _ = measure(tmp_path, [{"phi": 0, "theta": [60]}],
                   [{"centred_on": "incidence", "theta": [3.3, 10.7], "phi": [0, 90, 180, 270]}],
                   params={**RM1, "n": 68.0})
    assert_all_finite(d)
    assert not d.has_flag("roi_saturated").any()
    wi, wo = d.directions()
    truth = get_model("retrophong")(wi, wo, {**RM1, "n": 68.0})
    assert truth.max() > 1.3                    # the retro lobe is seen, 3.3° off its peak
    np.testing.assert_allclose(d["brdf_per_sr"], truth, rtol=0.03)


def test_specular_peak_beyond_every_exposure(tmp_path):
    """n = 10⁴ at the mirror direction: f ≈ 480 sr⁻¹, saturated even at the shortest exposure."""
    d, _ = measure(tmp_path, [{"phi": 0, "theta": [60]}],
                   [{"centred_on": "mirror", "theta": [0, 3.3], "phi": [0, 90]}],
                   model="modified_phong", params={"kd": 0.1, "ks": 0.3, "n": 1.0e4})
    assert_all_finite(d)
    peak = int(np.argmax(d["brdf_per_sr"]))
    assert d.flags[peak] and "roi_saturated" in d.flags[peak]       # a lower bound, and said so
    assert min(d.columns["exposures_s"][peak]) <= 2e-4
    assert not any("roi_saturated" in f for k, f in enumerate(d.flags) if k != peak)


def test_near_black_sample_is_low_signal(tmp_path):
    d, _ = measure(tmp_path, [{"phi": 0, "theta": [30]}], [{"points": [[20, 90], [40, 180]]}],
                   model="lambert", params={"kd": 1e-8})
    assert_all_finite(d)
    assert np.all(d.has_flag("low_signal"))
    assert all(max(ts) >= 1.0 for ts in d.columns["exposures_s"])     # it tried long exposures first


def test_huge_dynamic_range_inside_one_roi(tmp_path):
    """A lobe so narrow (n = 10⁵, ~0.3° wide) that the ROI spans ×100 between its corners."""
    params = {"kd": 1e-3, "ks": 1e-3, "n": 1.0e5}
    d, _ = measure(tmp_path, [{"phi": 0, "theta": [40]}], [{"centred_on": "mirror", "theta": [0.35], "phi": [90]}],
                   model="modified_phong", params=params)
    assert_all_finite(d)
    assert len(d.columns["exposures_s"][0]) >= 2          # bracketed: one exposure cannot hold the range
    assert d["roi_std_cd_m2"][0] > 0.5 * d["luminance_cd_m2"][0]
    assert not d.has_flag("roi_saturated")[0]
