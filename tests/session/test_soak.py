"""Soak (reduced form; the full paper-campaign form is benchmarks/soak.py): random transient
faults, a device outage, an axis alarm and a lamp burn-out with replacement; the final dataset
holds exactly the fault-free run's points, values within uncertainty, nothing lost."""


from repo_paths import E2E_CAMPAIGN as CAMPAIGN
from rig.config.campaign import load_campaign
from rig.config.rigfile import RigConfig
from rig.simulators.faults import FaultSchedule
from soak_runs import compare, run_fault_free, run_with_faults


def test_soak_reduced(tmp_path):
    campaign = load_campaign(CAMPAIGN)
    rig = RigConfig()
    schedule = FaultSchedule.random(103, seed=11, transient=12, silences=1)
    result = run_with_faults(campaign, CAMPAIGN, rig, tmp_path / "faulty", schedule)
    assert run_fault_free(campaign, CAMPAIGN, rig, tmp_path / "reference") == "complete"
    assert result.attempts[-1][0] == "complete", result.attempts
    assert result.fired == len(schedule.faults)
    statuses = [status for status, _ in result.attempts]
    assert statuses.count("failed") == 1 and "alarm" in result.attempts[0][1]     # the alarm stopped it once
    assert result.events.get("retry", 0) >= 8 and result.events["suspended"] >= 2   # outage + burn-out
    assert result.events["resume"] == 1
    c = compare(tmp_path / "faulty", tmp_path / "reference")
    assert c.same_points and c.duplicates == 0
    assert c.within_2u >= 0.9 and c.max_z < 5
