"""The lamp supply feeds the lamp nothing, and it is not the lamp (issue 29 item 2, issue 30 item 5): a run over the
protocol rig names the cause, and goes on once it is gone, instead of waiting `max_wait_s` for a "burnt out" lamp.

- The supply's watchdog switched the output off while rig was frozen (a server or a PC stalled longer than
  `lamp.watchdog_s`): the driver notices (`watchdog_expired`), the lamp's pause clears at once and the re-warm
  switches the lamp on again, ramped as at the start.
- An open interlock or a remote shut-down blocks the output: the pause names it (event `lamp_output_blocked`)
  and lasts until it is cleared.
"""

import json
from contextlib import contextmanager

import pytest
from shared import at_point, events, run, small_campaign, suspenders_run

from rig.acquisition.run import run_campaign
from rig.cli.main import _report_outcome
from rig.config.rigfile import RigConfig
from rig.simulators.rig import SimulatedRig

#: The built-in rig's `lamp.watchdog_s`, and a freeze longer than it.
WATCHDOG_S = 5.0
FREEZE_S = 8.0


@pytest.mark.parametrize("lost_reply", [False, True])
def test_after_a_freeze_longer_than_the_watchdog_the_lamp_is_switched_on_again_and_the_run_resumes(tmp_path,
                                                                                                   lost_reply):
    """`lost_reply`: the supply's `0` (expired) went to a connection the driver had given up during the stall, so
    the driver reads `-1` (off), as `rig sim serve` frozen longer than the watchdog showed (`watchdog_off`)."""
    def freeze(peers):           # rig time passes, nothing reaches the supply: its watchdog switches the output off
        supply = peers["lamp"]
        supply.world.clock.advance(FREEZE_S)
        assert supply.check_watchdog() is not None and not supply.world.lamp.output_on
        if lost_reply:
            assert supply.answer(b"SYSTem:COMmunicate:WATchdog?") == "0"
    ev, _ = suspenders_run(tmp_path, at_point(6, freeze))           # complete, each point once
    kinds = [e["event"] for e in ev]
    assert ("watchdog_off" if lost_reply else "watchdog_expired") in kinds and "suspend_timeout" not in kinds
    suspended = next(e for e in ev if e["event"] == "suspended")
    assert suspended["device"] == "lamp" and "watchdog switched the output off" in suspended["reason"]
    assert "burnt out" not in suspended["reason"]
    assert next(e for e in ev if e["event"] == "resumed")["waited_s"] < 1.0
    assert kinds.count("warmup_stable") == 2 and kinds.count("lamp_on") == 2       # ramped on again, re-warmed


def test_an_open_interlock_pauses_the_run_under_its_name_until_it_is_closed(tmp_path):
    state = {}

    def interlock(peers, done):
        supply = peers["lamp"]
        if done == 6 and "open" not in state:
            state["open"] = supply.world.clock.now()
            supply.set_interlock(True)
            supply.warn("Interlock open")
        elif "open" in state and "closed" not in state and supply.world.clock.now() > state["open"] + 100:
            state["closed"] = True
            supply.set_interlock(False)
    ev, _ = suspenders_run(tmp_path, interlock)
    blocked = [e for e in ev if e["event"] == "lamp_output_blocked"]
    assert len(blocked) == 1 and blocked[0]["status_a"] & 2048
    assert blocked[0]["reason"] == "interlock open (the supply's interlock input) (warnings: 301,Interlock open)"
    suspended = next(e for e in ev if e["event"] == "suspended")
    assert suspended["reason"].startswith("lamp output off: the supply blocks its output: interlock open")
    assert "burnt out" not in suspended["reason"]
    assert next(e for e in ev if e["event"] == "resumed")["waited_s"] >= 100


def test_a_remote_shut_down_that_stays_is_what_the_failed_run_names(tmp_path):
    def shut_down(peers):
        peers["lamp"].answer(b"SYSTem:RSD ON")          # another client's remote shut-down
    status, error, *_ = run(tmp_path, small_campaign(suspenders={"max_wait_s": 60}), inject=at_point(6, shut_down))
    assert status == "raised"
    assert str(error).startswith("lamp: paused 60 s and still: lamp output off: the supply blocks its output: "
                                 "remote shut-down (RSD) active")
    assert "burnt out" not in str(error)
    assert [e["event"] for e in events(tmp_path / "ds")].count("lamp_output_blocked") == 1


# -- the lamp's state at the end, when the supply stops answering (issue 30 item 6) ------------------------------
@contextmanager
def simulated(campaign, rig, sims):
    """`open_campaign_rig` that lets the test reach the peers (`sims[0].peers`)."""
    truth = campaign.sample.simulated_brdf
    with SimulatedRig(rig, truth.model, truth.params) as sim:
        sims.append(sim)
        yield sim.devices


def run_to_the_end(tmp_path, at=None):
    """Run a small campaign; `at(peers)` after point 5. The outcome and the dataset's manifest."""
    campaign, rig, sims = small_campaign(suspenders={"max_wait_s": 60}), RigConfig(), []
    outcome = run_campaign(campaign, rig, tmp_path / "ds", lambda c, r: simulated(c, r, sims),
                           progress=lambda p: at and p.done == 5 and at(sims[0].peers))
    return outcome, json.loads((tmp_path / "ds" / "dataset.json").read_text())


def test_a_supply_that_stops_answering_leaves_a_loud_warning_that_the_lamp_may_be_on(tmp_path, capsys):
    def supply_gone(peers):
        if peers["lamp"].url is not None:
            peers["lamp"].stop()                       # the supply's Ethernet is gone: every exchange is refused
            peers["arm"].inject("exception")           # and the run fails on an axis
    outcome, manifest = run_to_the_end(tmp_path, supply_gone)
    assert outcome.status == "failed"
    assert outcome.lamp_problem.startswith("lamp output off: lamp: OUTPut OFF failed 6 times")
    assert manifest["lamp_at_exit"] == {"lamp_off_confirmed": False, "lamp_problem": outcome.lamp_problem}
    _report_outcome(outcome, 0)
    err = capsys.readouterr().err
    assert "rig: WARNING: THE LAMP MAY STILL BE ON: the lamp supply did not confirm it switched off" in err
    assert "OUTPut OFF failed 6 times" in err and "Switch it off at the supply." in err


def test_a_lamp_confirmed_off_is_recorded_as_such_and_nothing_is_said(tmp_path, capsys):
    outcome, manifest = run_to_the_end(tmp_path)
    assert outcome.status == "complete" and outcome.lamp_problem is None
    assert manifest["lamp_at_exit"] == {"lamp_off_confirmed": True, "lamp_problem": None}
    _report_outcome(outcome, 0)
    assert "LAMP" not in capsys.readouterr().err
