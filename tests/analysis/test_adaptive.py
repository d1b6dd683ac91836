"""Choosing an adaptive campaign's next batch (rig.analysis.adaptive), on rows made from a known BRDF."""

import numpy as np
import pytest

from repo_paths import TEST_CAMPAIGNS
from rig.analysis import adaptive
from rig.analysis.adaptive import (
    MIN_BATCH_VIEWS,
    binned,
    choose_batch,
    represented_width_deg,
    rows_dataset,
    series_batch,
    spread_by_gain,
)
from rig.analysis.predict import measured_domain
from rig.analysis.validation import TruthPredictor
from rig.config.campaign import load_campaign
from rig.config.rigfile import RigConfig
from rig.physics import geometry as geo
from rig.planning.candidates import candidate_plan, pattern_ids
from rig.planning.collisions import zones_of
from rig.planning.plan import build_plan

CAMPAIGN = load_campaign(TEST_CAMPAIGNS / "e2e-adaptive.yaml")
RIG = RigConfig()


def rows_of(points, noise_rel=0.0, seed=0):
    truth = TruthPredictor(CAMPAIGN.sample.simulated_brdf.model, CAMPAIGN.sample.simulated_brdf.params)
    rng = np.random.default_rng(seed)
    rows = []
    for p in points:
        f = float(truth.predict(p.theta_i_deg, p.phi_i_deg, p.theta_o_deg, p.phi_o_deg).brdf_per_sr)
        f *= 1 + noise_rel * rng.standard_normal()
        rows.append({"point_id": p.point_id, "brdf_per_sr": f, "u_brdf_per_sr": 0.003 * f, "flags": ""})
    return rows


def batch_after(rows, measured, max_s=np.inf):
    plan = build_plan(CAMPAIGN, RIG)
    return choose_batch(rows, candidate_plan(CAMPAIGN, RIG), measured, plan.points[-1].motors_deg, RIG.axes,
                        zones_of(RIG), batch_points=8, capture_s=0.05, reading_s=0.5, max_s=max_s)


def test_bins_are_quarter_octaves():
    x = np.array([1.0, 1.09, 1.1, 2.0, 0.0])
    assert binned(x) == pytest.approx([1.0, 1.0, 2 ** 0.25, 2.0, 0.0])


def test_a_batch_spreads_over_the_largest_gains():
    points = [p for p in candidate_plan(CAMPAIGN, RIG).points if p.theta_i_deg == pytest.approx(40.0)]
    gain = np.zeros(len(points))
    gain[[3, 4, 20]] = [1.0, 1.0, 0.5]          # 3 and 4 are neighbours next to retroreflection
    chosen = spread_by_gain(points, gain, 3)
    assert chosen[0] == 3 and 20 in chosen      # the neighbour 4 is damped below the far view 20
    assert spread_by_gain(points, np.zeros(len(points)), 3) == []


def test_the_next_batch_is_deterministic_under_measurement_noise():
    """What a resumed run relies on: re-measured points differ by their noise, and that must not change the batch."""
    first = build_plan(CAMPAIGN, RIG).points
    measured = {p.point_id for p in first}
    a = batch_after(rows_of(first, 0.002, seed=1), measured)
    b = batch_after(rows_of(first, 0.002, seed=2), measured)
    assert a is not None and [p.point_id for p in a.points] == [p.point_id for p in b.points]
    assert {p.series for p in a.points} == {a.series} and len(a.points) <= 8
    assert 0 < a.estimated_s and a.gain > 0 and a.max_u_rel > 0


def test_no_batch_once_every_candidate_is_measured():
    everything = candidate_plan(CAMPAIGN, RIG).points
    assert batch_after(rows_of(everything), {p.point_id for p in everything}) is None


def test_the_bend_in_theta_i_is_what_linear_interpolation_leaves_out():
    """ln f = 1e-3·θi² on every view: the quadratic through 20, 40 and 60° is exact, so the bend at θi between two
    measured incidences is 1e-3·(θ − 20)(40 − θ) (0.1 at 30°), and nothing at a measured incidence."""
    candidates = candidate_plan(CAMPAIGN, RIG).points
    measured = [p for p in candidates if any(p.theta_i_deg == pytest.approx(t) for t in (20.0, 40.0, 60.0))]
    rows = [{"point_id": p.point_id, "brdf_per_sr": float(np.exp(1e-3 * p.theta_i_deg ** 2)), "u_brdf_per_sr": 0.0,
             "flags": ""} for p in measured]
    domain = measured_domain(rows_dataset(rows, {p.point_id: p for p in candidates}))
    at = [p for p in candidates if any(p.theta_i_deg == pytest.approx(t) for t in (25.0, 30.0, 40.0, 55.0))]
    theta = np.array([p.theta_i_deg for p in at])
    xy = geo.disk_coordinates(np.array([p.theta_o_deg for p in at]), np.array([p.phi_o_deg for p in at]),
                              np.array([p.phi_i_deg for p in at]))
    expected = np.where(theta < 40, 1e-3 * (theta - 20) * (40 - theta), 1e-3 * (theta - 40) * (60 - theta))
    lo, hi, w, _ = domain.brackets(theta)
    f_lo, f_hi = domain.at_incidence(lo, theta, xy)[0], domain.at_incidence(hi, theta, xy)[0]
    assert domain.theta_bend(theta, xy, lo, hi, w, f_lo, f_hi) == pytest.approx(expected, abs=1e-9)
    assert expected[np.isclose(theta, 30.0)] == pytest.approx(0.1)


def test_a_series_stands_for_half_the_gap_to_its_measured_neighbours():
    measured = np.array([0.0, 30.0, 60.0, 85.0])
    assert represented_width_deg(measured, 45.0, (0.0, 85.0)) == pytest.approx(15.0)
    assert represented_width_deg(measured, 30.0, (0.0, 85.0)) == pytest.approx(30.0)
    assert represented_width_deg(measured, 0.0, (0.0, 85.0)) == pytest.approx(15.0)
    assert represented_width_deg(measured, 85.0, (0.0, 85.0)) == pytest.approx(12.5)
    assert represented_width_deg(np.array([]), 40.0, (40.0, 40.0)) == pytest.approx(1.0)   # the least width


def test_only_a_batch_that_fits_in_what_is_left_is_chosen():
    """A batch is never cut (a part of a pattern leaves a lopsided hull): one that does not fit is passed over."""
    first = build_plan(CAMPAIGN, RIG).points
    rows, measured = rows_of(first), {p.point_id for p in first}
    best = batch_after(rows, measured)
    assert best is not None
    fitting = batch_after(rows, measured, max_s=best.estimated_s - 1e-6)
    assert fitting is None or (fitting.estimated_s < best.estimated_s and fitting.series != best.series)
    assert batch_after(rows, measured, max_s=0.4) is None                   # not even the E⊥ reading fits


def test_a_batch_is_a_part_of_the_pattern_only_where_the_rest_gains_little():
    """Gain per second decides how much of a pattern a batch takes: where a few views carry the gain the batch is
    their part of the pattern (the rest is left for later); where every view gains alike, the whole pattern."""
    candidates = candidate_plan(CAMPAIGN, RIG)
    points = [p for p in candidates.points if p.theta_i_deg == pytest.approx(40.0)]
    start = build_plan(CAMPAIGN, RIG).points[-1].motors_deg

    def batch(gain):
        return series_batch(candidates, points[0].series, points, gain, 10.0, 0.1, start, RIG.axes, zones_of(RIG),
                            len(points), 0.05, 0.5)

    uniform = batch(np.ones(len(points)))
    assert len(uniform.points) == len(points)
    few = np.full(len(points), 1e-4)
    few[:: max(1, len(points) // 4)] = 1.0
    partial = batch(few)
    assert MIN_BATCH_VIEWS <= len(partial.points) < len(points)
    assert {p.point_id for p in partial.points} >= {points[k].point_id for k in np.flatnonzero(few == 1.0)}
    assert partial.score_per_s > uniform.score_per_s * few.sum() / len(points)


def test_an_incidence_not_measured_yet_is_taken_whole_as_its_patterns_own_views():
    """A new incidence becomes a bracket of every direction between its neighbours: a part of it (or rings between
    the table's without the table's own) would leave a lopsided hull there (issue 33). With every candidate at the
    measured incidences taken, the next batch is at a new incidence and is its pattern's own views, all of them."""
    candidates = candidate_plan(CAMPAIGN, RIG)
    first = build_plan(CAMPAIGN, RIG).points
    done = {round(p.theta_i_deg, 6) for p in first}
    measured = {p.point_id for p in candidates.points if round(p.theta_i_deg, 6) in done}
    rows = rows_of([p for p in candidates.points if p.point_id in measured])
    own = pattern_ids(CAMPAIGN, candidates)
    batch = choose_batch(rows, candidates, measured, first[-1].motors_deg, RIG.axes, zones_of(RIG), batch_points=256,
                         capture_s=0.05, reading_s=0.5, pattern=own)
    assert batch is not None and round(batch.points[0].theta_i_deg, 6) not in done
    series = [p.point_id for p in candidates.points if p.series == batch.series]
    assert sorted(p.point_id for p in batch.points) == sorted(pid for pid in series if pid in own)
    assert len(batch.points) < len(series)                  # the rings between are left for a later batch


def test_one_candidate_with_an_absurd_u_does_not_decide_the_batch(monkeypatch):
    """u/(f + τ) of 20 (a hull's sliver, a steep bend) says "not known", as 1 does; counted as 20² it outweighed a
    whole incidence of candidates at 0.9 and let the measurement noise it amplifies pick the batch, which broke a
    resumed run's determinism (tests/session/test_adaptive_sampling.py)."""
    candidates = candidate_plan(CAMPAIGN, RIG)
    first = build_plan(CAMPAIGN, RIG).points
    measured = {p.point_id for p in first}
    left = [p for p in candidates.points if p.point_id not in measured]
    lone, broad = 8, 11                                                  # the series at 40° and at 55°
    u = np.array([0.9 if p.series == broad else 1e-3 for p in left])
    u[next(k for k, p in enumerate(left) if p.series == lone)] = 20.0
    monkeypatch.setattr(adaptive, "candidate_u_rel", lambda *args, **kwargs: (u, np.array([0.0, 30.0, 85.0])))
    batch = choose_batch(rows_of(first), candidates, measured, first[-1].motors_deg, RIG.axes, zones_of(RIG),
                         batch_points=8, capture_s=0.05, reading_s=0.5)
    assert batch is not None and batch.series == broad
