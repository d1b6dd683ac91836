"""The lamp supply feeds the lamp nothing, and it is not the lamp (issue 29 item 2, issue 30 item 5): a run over the
protocol rig names the cause, and goes on once it is gone, instead of waiting `max_wait_s` for a "burnt out" lamp.

- The supply's watchdog switched the output off while rig was frozen (a server or a PC stalled longer than
  `lamp.watchdog_s`): the driver notices (`watchdog_expired`), the lamp's pause clears at once and the re-warm
  switches the lamp on again, ramped as at the start.
- An open interlock or a remote shut-down blocks the output: the pause names it (event `lamp_output_blocked`)
  and lasts until it is cleared.
"""

from test_runner import at_point, events, run, small_campaign, suspenders_run

#: The built-in rig's `lamp.watchdog_s`, and a freeze longer than it.
WATCHDOG_S = 5.0
FREEZE_S = 8.0


def test_after_a_freeze_longer_than_the_watchdog_the_lamp_is_switched_on_again_and_the_run_resumes(tmp_path):
    def freeze(peers):           # rig time passes, nothing reaches the supply: its watchdog switches the output off
        supply = peers["lamp"]
        supply.world.clock.advance(FREEZE_S)
        assert supply.check_watchdog() is not None and not supply.world.lamp.output_on
    ev, _ = suspenders_run(tmp_path, at_point(6, freeze))           # complete, each point once
    kinds = [e["event"] for e in ev]
    assert "watchdog_expired" in kinds and "suspend_timeout" not in kinds
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
