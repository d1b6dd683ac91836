"""The served world's clock (rig.simulators.clock.ServedClock): `speed` rig seconds per wall second, standing still
while the world computes, so that rendering a frame is no rig time (a real frame costs exposure + readout). Wall time
is a fake here (the clock's `time.monotonic` and `time.sleep`), so nothing depends on the machine's speed."""

import pytest

from rig.config.rigfile import RigConfig
from rig.core.values import Window
from rig.physics.brdf_models import get_model
from rig.simulators import clock as clock_module
from rig.simulators.camera import SimCamera
from rig.simulators.clock import ServedClock, SimClock
from rig.simulators.world import SimWorld


class FakeWall:
    """`time` as the clocks see it: wall time moves only when told (or slept)."""

    def __init__(self) -> None:
        self.t = 1000.0

    def monotonic(self) -> float:
        return self.t

    def sleep(self, seconds: float) -> None:
        self.t += seconds


@pytest.fixture
def wall(monkeypatch) -> FakeWall:
    fake = FakeWall()
    monkeypatch.setattr(clock_module, "time", fake)
    monkeypatch.setattr("rig.drivers.wallclock.time", fake)
    return fake


def test_rig_time_runs_speed_times_wall_time(wall):
    clock = ServedClock(200.0)
    wall.t += 0.5
    assert clock.now() == pytest.approx(100.0)


def test_rig_time_stands_still_while_the_world_computes_and_goes_on_from_there(wall):
    clock = ServedClock(200.0)
    wall.t += 0.1
    with clock.computing():
        held = clock.now()
        wall.t += 0.03                       # a 30 ms render: 6 rig s, were it counted
        assert clock.now() == pytest.approx(held, abs=1e-12)
        with clock.computing():              # holds nest
            wall.t += 0.01
        assert clock.now() == pytest.approx(held, abs=1e-12)
    assert clock.now() == pytest.approx(20.0)
    wall.t += 0.01
    assert clock.now() == pytest.approx(22.0)


def test_a_sleep_lasts_its_rig_time_of_the_clock_however_long_a_hold_in_it(wall):
    """A peer sleeping on the world's clock while another thread holds it wakes after its rig time of the clock,
    not of the wall (here the hold is made by the check each slice calls)."""
    clock = ServedClock(100.0)
    holds = []

    def hold_once() -> None:
        if not holds:
            holds.append(1)
            with clock.computing():
                wall.t += 5.0                # five wall seconds of computing: no rig time

    clock.sleep_check = hold_once
    start_wall = wall.t
    clock.sleep(10.0)
    assert clock.now() == pytest.approx(10.0, abs=clock.scale * clock.CHECK_SLICE_S)
    assert wall.t - start_wall == pytest.approx(5.0 + 0.1, abs=clock.CHECK_SLICE_S)


def test_a_frame_rendered_on_a_served_world_costs_no_rig_time_however_long_it_renders(wall, monkeypatch):
    world = SimWorld(RigConfig(), get_model("lambert"), {"kd": 0.5}, clock=ServedClock(200.0))
    camera = SimCamera(world)
    rendering = camera.luminance

    def slow_luminance(*args, **kwargs):
        wall.t += 0.25                       # 50 rig s at speed 200, were it counted
        return rendering(*args, **kwargs)

    monkeypatch.setattr(camera, "luminance", slow_luminance)
    before = world.clock.now()
    frame, duration_s = camera.render(0.01, Window(0, 0, 16, 16), dark=False)
    assert world.clock.now() == pytest.approx(before, abs=1e-9)
    assert frame.meta["start_s"] == pytest.approx(before, abs=1e-9)
    assert 0.01 <= duration_s < 1.0          # what the frame costs: its exposure and readout


def test_the_in_process_world_computes_as_before():
    world = SimWorld(RigConfig(), get_model("lambert"), {"kd": 0.5}, clock=SimClock())
    with world.computing():
        world.clock.sleep(1.0)
    assert world.clock.now() == pytest.approx(1.0)
