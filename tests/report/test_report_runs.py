"""The report of a resumed campaign (issue 35): rig time is the campaign's total, both warm-ups are listed, the E⊥
trend is fitted within each run (the lamp was off between them), and an old dataset's runs are placed in turn."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from rig.report.content import conditions
from rig.report.html import _conditions_section


def two_runs(restarted: bool) -> list[dict]:
    """Two runs, each warm-up then E⊥ rising 10 lx an hour; the second run's lamp 50 lx lower (a night off).
    `restarted`: written before rig time continued (the second run's rig time starts at 0 again)."""
    def run(t0: float, level: float) -> list[dict]:
        return [{"event": "lamp_on", "rig_time_s": t0 + 5.0, "current_a": 4.17, "voltage_v": 11.6},
                {"event": "warmup_stable", "rig_time_s": t0 + 605.0, "warmup_s": 600.0, "change_rel": 0.001,
                 "lamp_voltage_v": 12.0},
                *({"event": "illuminance", "rig_time_s": t0 + 605.0 + h * 3600.0,
                   "illuminance_normal_lx": level + 10.0 * h, "u_lx": 4.0} for h in range(3)),
                {"event": "safe_state", "rig_time_s": t0 + 605.0 + 2 * 3600.0}]
    first_end = 605.0 + 2 * 3600.0
    return [*run(0.0, 5000.0), {"event": "resume", "previous_status": "interrupted"},
            *run(0.0 if restarted else first_end, 4950.0)]


@pytest.mark.parametrize("restarted", [False, True])
def test_a_resumed_campaigns_conditions(restarted):
    manifest = {"resumes": [{"previous_status": "interrupted"}], "rig_time_s": 2 * (605.0 + 7200.0)}
    if restarted:
        manifest["rig_time_s"] = 605.0 + 7200.0          # an old manifest: the last run's rig time only
    else:
        manifest["runs"] = [{"run": 0}, {"run": 1}]
    c = conditions(two_runs(restarted), manifest)
    assert c.rig_time_s == pytest.approx(2 * 7805.0)
    assert [len(r.warmups) for r in c.runs] == [1, 1] and c.runs[1].warmups[0].end_s == pytest.approx(7805.0 + 605.0)
    t = c.illuminance.rig_time_s
    assert (t[1:] > t[:-1]).all()                                    # one axis, in measuring order
    assert c.illuminance.slope_rel_per_h == pytest.approx(10.0 / c.illuminance.e_perp_lx.mean())   # not the jump
    assert c.illuminance.run_slopes_rel_per_h() == pytest.approx([10.0 / 4975.0] * 2, rel=0.01)
    if not restarted:
        html = _conditions_section(SimpleNamespace(conditions=c))       # type: ignore[arg-type]
        assert "Lamp warm-ups" in html and "run 2 at 2.34 h: 10 min" in html and "run 2: 0.2" in html
