"""rig.acquisition.eta on its own: the warm-up in the first ETA, its rest while it goes, the measured rate after."""

from __future__ import annotations

import pytest

from rig.acquisition.eta import Eta


class Clock:
    t = 0.0

    def __call__(self) -> float:
        return self.t


def test_the_first_eta_includes_the_expected_warm_up_and_its_rest_while_it_goes():
    clock = Clock()
    eta = Eta(clock, warmup_s=500.0)
    eta.plan({"a": 10.0, "b": 10.0, "c": 10.0}, done_ids={"c"})
    assert eta.left_s() == pytest.approx(520.0) and eta.stage == "starting"
    eta.warming(120.0)
    assert eta.left_s() == pytest.approx(140.0) and eta.stage == "warm-up"
    eta.warming(0.0)
    assert eta.left_s() == pytest.approx(20.0) and eta.stage == "between"


def test_points_left_take_the_measured_rate_and_pauses_do_not_count():
    clock = Clock()
    eta = Eta(clock)
    eta.plan({"a": 10.0, "b": 10.0}, done_ids=())
    eta.measuring(True)
    clock.t = 40.0
    eta.done("a")
    assert eta.left_s() == pytest.approx(40.0) and eta.stage == "measuring"    # 4 × the plan's estimate
    eta.measuring(False)
    clock.t = 1000.0                                                           # a pause: not measuring time
    assert eta.left_s() == pytest.approx(40.0)
    eta.undone(["a"])
    assert eta.left_s() == pytest.approx(80.0)
