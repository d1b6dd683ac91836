"""The sampling study's bookkeeping (rig.bench): drawn samples, the budgets scored as prefixes of one adaptive
run, and the verdicts and bars over draws, on synthetic records (no campaign is run)."""

from __future__ import annotations

import json

import pytest

from rig.bench.draws import FAMILIES, draw, draws
from rig.bench.sampling import TABLE, Result, WorstPairs, budget_prefixes
from rig.bench.sampling_report import distribution, smallest_reaching, verdict


def test_a_draw_is_the_same_whichever_others_are_drawn_with_it():
    assert draws(5, 3, first=2)[1] == draw(5, 3) == draws(5, 10)[3]
    assert [d.family for d in draws(5, 6)] == [*FAMILIES, FAMILIES[0]]
    assert draw(5, 3).params != draw(6, 3).params
    with pytest.raises(ValueError, match="unknown family"):
        draw(5, 0, ("no_such_family",))


def test_a_budget_is_scored_on_the_batches_that_fit_in_it(tmp_path):
    """Batches are planned to end at 100, 180 and 260 s of a 1000 s table: 0.1 keeps none (the first pass only),
    0.2 the first two; each prefix ends when the next batch was chosen (rig time after warm-up)."""
    events = [{"event": "warmup_stable", "rig_time_s": 300.0}]
    for k, (planned, chosen_at) in enumerate([(100.0, 395.0), (180.0, 480.0), (260.0, 570.0)]):
        events.append({"event": "adaptive_batch", "rig_time_s": chosen_at, "planned_rig_time_s": planned,
                       "points": [f"{k}-a", f"{k}-b"]})
    events.append({"event": "sampling_done", "rig_time_s": 660.0})
    (tmp_path / "events.jsonl").write_text("".join(json.dumps(e) + "\n" for e in events))
    prefixes = budget_prefixes(tmp_path, 1000.0, [0.2, 0.05, 0.5])
    assert [p[0] for p in prefixes] == [0.05, 0.2, 0.5]
    assert prefixes[0][1] == {"0-a", "0-b", "1-a", "1-b", "2-a", "2-b"} and prefixes[0][2] == pytest.approx(95.0)
    assert prefixes[1][1] == {"2-a", "2-b"} and prefixes[1][2] == pytest.approx(270.0)
    assert prefixes[2][1] == set() and prefixes[2][2] == pytest.approx(360.0)


def result(index: int, strategy: str, fraction: float | None, rig_min: float, p95: float) -> Result:
    errors = {f"{g}_{s}": p95 for g in ("diffuse", "forward", "retro") for s in ("median", "p95")}
    return Result(f"lambert#{index}", "lambert", 9, strategy, fraction, 100, 60 * rig_min, 1.0,
                  {**errors, "all_p95": p95, "albedo_max_rel": 0.0}, WorstPairs(40.0, 30.0, 0.1, 50))


def test_the_bars_count_draws_by_the_smallest_budget_that_reaches_the_table():
    """Draw 0 reaches the table at 0.2×, draw 1 only at 0.45×, draw 2 never: 1 of 3 by 0.25×, 2 by 0.5×."""
    results = [result(k, TABLE, None, 100.0, 0.05) for k in range(3)]
    results += [result(0, "adaptive ×0.1", 0.1, 10.0, 0.2), result(0, "adaptive ×0.25", 0.25, 20.0, 0.05)]
    results += [result(1, "adaptive ×0.25", 0.25, 24.0, 0.08), result(1, "adaptive ×0.5", 0.5, 45.0, 0.0505)]
    results += [result(2, "adaptive ×0.25", 0.25, 24.0, 0.08), result(2, "adaptive ×0.5", 0.5, 49.0, 0.07)]
    group = [r for r in results if r.draw == "lambert#0"]
    assert smallest_reaching(group).fraction == 0.25
    assert "reached by adaptive ×0.25 in 0.200×" in verdict(group)
    assert "NOT reached" in verdict([r for r in results if r.draw == "lambert#2"])
    text = distribution(results)
    assert "reached by ≤ 0.25×: 1/3 draws with an adaptive run (33%; bar ≥ 80%: NOT met)" in text
    assert "by ≤ 0.5×: 2/3 (NOT every draw)" in text
    assert "0.20, 0.45, —" in text


def test_road_quantities_beyond_the_rigs_reach_never_decide_but_are_named():
    table, adaptive = result(0, TABLE, None, 100.0, 0.05), result(0, "adaptive ×0.25", 0.25, 20.0, 0.05)
    table.errors.update(R_L_rel=0.01, Qd_rel=0.01)
    adaptive.errors.update(R_L_rel=0.2, Qd_rel=0.01)
    assert smallest_reaching([table, adaptive]) is adaptive
    assert "its R_L error (extrapolated) is worse than the table's" in verdict([table, adaptive])
