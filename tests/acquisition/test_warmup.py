"""rig.acquisition.warmup on its own: the rule, its events, and the progress it reports while nothing moves."""

from __future__ import annotations

from types import SimpleNamespace

import pytest

from rig.acquisition.eta import Eta
from rig.acquisition.warmup import REPORT_EVERY_S, warm_up
from rig.config.campaign import Lamp
from rig.config.rigfile import RigConfig


class Bench:
    """A lamp and a meter whose readings are given, on a clock that only `wait` advances."""

    def __init__(self, readings: list[float]):
        self.t, self.readings = 0.0, list(readings)
        self.events: list[tuple[str, dict]] = []
        self.reports: list[str] = []
        lamp = SimpleNamespace(set_current=lambda *a, **k: None, set_output=lambda on: None,
                               measure_current_a=lambda: 4.17, measure_voltage_v=lambda: 12.0)
        meter = SimpleNamespace(read=lambda: SimpleNamespace(illuminance_lx=self.readings.pop(0)))
        self.dev = SimpleNamespace(lamp=lamp, meter=meter)

    def wait(self, seconds: float) -> None:
        self.t += seconds

    def run(self, lamp: Lamp, eta: Eta | None = None):
        return warm_up(lamp, RigConfig(), self.dev, self.wait, lambda: self.t,  # type: ignore[arg-type]
                       lambda kind, **f: self.events.append((kind, f)), self.reports.append, eta)


def test_the_warm_up_ends_at_the_first_steady_check_and_says_each_check():
    bench = Bench([1000.0, 1010.0, 1004.0, 1005.0])          # changes 1 %, 0.6 %, 0.1 %
    eta = Eta(lambda: bench.t, warmup_s=200.0)
    warmed = bench.run(Lamp(warmup_min_s=60, warmup_check_s=30, warmup_stable_rel=0.002), eta)
    assert warmed.stable and warmed.warmup_s == pytest.approx(150.0) and warmed.lamp_voltage_v == 12.0
    kinds = [k for k, _ in bench.events]
    assert kinds == ["lamp_on", "warmup_wait", "warmup_check", "warmup_check", "warmup_stable"]    # min 60, check 30
    assert bench.events[1][1] == {"warmup_s": 30.0, "expected_left_s": 170.0}
    check = bench.events[2][1]
    assert check["change_rel"] == pytest.approx(10 / 1010) and check["warmup_s"] == pytest.approx(90.0)
    assert check["expected_left_s"] == pytest.approx(110.0)          # to the expected 200 s
    assert eta.warmup_left_s == 0.0 and eta.stage == "between"


def test_the_warm_up_reports_while_it_waits_with_the_expected_rest():
    """Issue 35: the progress line stayed at "rig 0:00:05" for the whole warm-up, as if hung."""
    bench = Bench([1000.0, 1000.0])
    eta = Eta(lambda: bench.t, warmup_s=400.0)
    bench.run(Lamp(warmup_min_s=300, warmup_check_s=60), eta)
    assert len(bench.reports) >= (300 + 60) / REPORT_EVERY_S
    assert bench.reports[0] == "lamp warm-up 0:00, ≈ 6:40 left"
    assert "lamp warm-up 5:00, ≈ 1:40 left" in bench.reports


def test_a_warm_up_that_never_settles_ends_at_the_maximum():
    bench = Bench([1000.0 * (1 + 0.01 * k) for k in range(20)])
    warmed = bench.run(Lamp(warmup_min_s=60, warmup_max_s=150, warmup_check_s=30))
    assert not warmed.stable and warmed.warmup_s == pytest.approx(150.0)
    assert bench.events[-1][0] == "warmup_not_stable"
