"""Keep-alives run during sleeps, in rig time, on every clock (the lamp supply's watchdog feed)."""

from __future__ import annotations

import pytest

from rig.drivers.wallclock import WallClock
from rig.simulators.clock import SimClock


def test_sim_clock_feeds_at_every_period_of_a_long_sleep():
    clock = SimClock(pace=0)
    fed: list[float] = []
    clock.keep_alive(2.0, lambda: fed.append(clock.now()))
    clock.sleep(10.0)
    assert fed == pytest.approx([2.0, 4.0, 6.0, 8.0, 10.0])
    assert clock.now() == pytest.approx(10.0)


def test_short_sleeps_add_up_to_a_feed_and_cancel_stops_it():
    clock = SimClock(pace=0)
    fed: list[float] = []
    cancel = clock.keep_alive(1.0, lambda: fed.append(clock.now()))
    for _ in range(5):
        clock.sleep(0.3)
    assert fed == pytest.approx([1.0])          # the sleep that passes the due time is split there
    cancel()
    clock.sleep(5.0)
    assert len(fed) == 1


def test_advance_is_instrument_time_without_feeds_or_stop_checks():
    clock = SimClock(pace=0)
    fed: list[float] = []
    clock.keep_alive(1.0, lambda: fed.append(clock.now()))

    def stop() -> None:
        raise RuntimeError("stop")
    clock.sleep_check = stop
    clock.advance(3.0)
    assert fed == [] and clock.now() == pytest.approx(3.0)
    clock.sleep_check = None
    clock.sleep(0.0)                            # the next sleep runs the overdue feed at once
    assert fed == pytest.approx([3.0])


def test_a_feed_that_sleeps_does_not_feed_itself():
    clock = SimClock(pace=0)
    fed: list[float] = []

    def feed() -> None:
        fed.append(clock.now())
        clock.sleep(0.5)                        # e.g. a retry's back-off inside the feed
    clock.keep_alive(1.0, feed)
    clock.sleep(3.0)
    assert len(fed) >= 2 and all(b - a >= 1.0 - 1e-9 for a, b in zip(fed, fed[1:]))


def test_scaled_wall_clock_feeds_in_rig_time():
    clock = WallClock(scale=200.0)
    fed: list[float] = []
    clock.keep_alive(2.0, lambda: fed.append(clock.now()))
    start = clock.now()
    clock.sleep(10.0)                            # 50 ms of wall time
    assert clock.now() - start >= 10.0 - 1e-6
    assert len(fed) >= 3                         # every 2 s of rig time; a loaded machine may merge some
    assert all(b > a for a, b in zip(fed, fed[1:]))


@pytest.mark.parametrize("period", [0.0, -1.0, float("nan"), float("inf")])
def test_keep_alive_period_must_be_positive(period):
    with pytest.raises(ValueError, match="keep-alive period"):
        SimClock(pace=0).keep_alive(period, lambda: None)


@pytest.mark.parametrize("scale", [0.0, -2.0, float("nan")])
def test_wall_clock_scale_must_be_positive(scale):
    with pytest.raises(ValueError, match="clock scale"):
        WallClock(scale)
