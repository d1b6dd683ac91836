"""Thorlabs FW102C filter wheel: the driver against its pty peer (moves in rig time, identity, every fault).

The peer is rebuilt from the FW102C manual Rev H 2014 p. 11 and the exchanges github delmic/odemis
src/odemis/driver/tlfw.py records; its own replays are in tests/simulators/test_fw102c_peer.py.
"""

from types import SimpleNamespace

import pytest
from shared import ANSWERED_S, SILENCE_S

from rig.config.rigfile import RigConfig
from rig.core.errors import DeviceError
from rig.drivers.fw102c import FW102C
from rig.drivers.retry import DEFAULT_RETRY
from rig.physics.brdf_models import get_model
from rig.simulators.clock import SimClock
from rig.simulators.fw102c_peer import FW102CPeer
from rig.simulators.world import SimWorld


@pytest.fixture
def world() -> SimWorld:
    return SimWorld(RigConfig(), get_model("lambert"), {"kd": 0.5})


@pytest.fixture
def peer(world, no_leaks):
    with FW102CPeer(world) as p:
        yield p


def connect(path, world, events, timeout_s=ANSWERED_S) -> FW102C:
    wheel = FW102C(path, clock=world.clock, timeout_s=timeout_s)
    wheel.events = lambda kind, **fields: events.append((kind, fields))
    return wheel


@pytest.fixture
def wheel(peer, world, events):
    w = connect(peer.path, world, events)
    yield w
    w.close()


@pytest.fixture
def silent_wheel(peer, world, events):
    """A wheel whose lost replies time out quickly (SILENCE_S)."""
    w = connect(peer.path, world, events, SILENCE_S)
    yield w
    w.close()


def kinds(events) -> list[str]:
    return [kind for kind, _ in events]


@pytest.mark.parametrize("positions", [6, 12])
def test_connect_identifies_and_sets_high_speed_with_sensors_off(world, events, no_leaks, positions):
    with FW102CPeer(world, positions, position=2) as peer:
        wheel = connect(peer.path, world, events)
        assert wheel.position() == 2
        wheel.close()
    assert wheel.identity() == f"THORLABS FW102C/FW212C Filter Wheel version 1.04 ({positions} positions)"
    assert wheel.positions == positions and peer.speed == 1 and peer.sensors == 0 and peer.saved is None
    assert events == []


def test_from_rig_connects_at_once(peer, world, events):
    wheel = FW102C.from_rig(clock=world.clock, settings=SimpleNamespace(), address=peer.path, timeout_s=ANSWERED_S)
    try:
        assert wheel.positions == 6 and wheel.position() == 1
    finally:
        wheel.close()


@pytest.mark.parametrize("start, target, seconds", [(1, 4, 3.0), (1, 2, 1.0), (1, 6, 1.0), (5, 2, 3.0), (2, 6, 2.0)])
def test_moves_cost_one_second_per_position_of_rig_time(wheel, peer, world, events, start, target, seconds):
    """At high speed, the shorter way round; the wheel's time passes on the rig clock (an unpaced simulated
    clock: no wall time is waited for it)."""
    assert isinstance(world.clock, SimClock) and world.clock.pace == 0
    wheel.move_to(start)
    t0 = world.clock.now()
    wheel.move_to(target)
    assert world.clock.now() - t0 == pytest.approx(seconds)
    assert peer.position == wheel.position() == target and events == []


def test_a_twelve_position_wheel_moves_across(world, events, no_leaks):
    with FW102CPeer(world, 12) as peer:
        wheel = connect(peer.path, world, events)
        t0 = world.clock.now()
        wheel.move_to(7)
        wheel.move_to(12)
        wheel.close()
    assert world.clock.now() - t0 == pytest.approx(6.0 + 5.0) and peer.position == 12


def test_moving_to_where_it_is_costs_nothing(wheel, peer, world):
    wheel.move_to(4)
    peer.inject("no_reply")                 # a line sent now would be lost and retried: none is
    t0 = world.clock.now()
    wheel.move_to(4)
    assert world.clock.now() == t0
    assert peer.take_fault() == "no_reply"


def test_a_position_the_wheel_lacks_is_refused(wheel, peer):
    with pytest.raises(DeviceError, match="^attenuator: no filter position 7: the wheel has positions 1 … 6$"):
        wheel.move_to(7)
    assert peer.position == 1


@pytest.mark.parametrize("fault", ["no_reply", "garbled"])
def test_a_spoilt_position_reply_is_retried(silent_wheel, peer, events, fault):
    silent_wheel.move_to(3)
    peer.inject(fault)
    assert silent_wheel.position() == 3
    assert kinds(events) == ["retry", "reconnect"]


def test_a_garbled_move_reply_is_not_moved_again(wheel, peer, world, events):
    """The wheel moved; its prompt came garbled; the reconnect finds it there: one move's time only."""
    peer.inject("garbled")
    t0 = world.clock.now()
    wheel.move_to(4)
    assert world.clock.now() - t0 == pytest.approx(3.0 + DEFAULT_RETRY.backoff_s)
    assert peer.position == 4 and kinds(events) == ["retry", "reconnect"]
    assert "garbled reply to 'pos=4'" in events[0][1]["error"]


def test_a_stuck_wheel_is_a_persistent_error(wheel, peer, world, events):
    peer.inject("stuck")
    with pytest.raises(DeviceError, match=r"^attenuator: 'pos=3' ended at position 1, not 3 "
                                          r"\(is the wheel jammed or held\?\)$") as err:
        wheel.move_to(3)
    assert not err.value.transient and events == []
    assert peer.position == wheel.position() == 1
    wheel.move_to(3)                         # free again
    assert peer.position == 3


def test_a_silent_wheel_is_unanswered_after_the_retries(silent_wheel, peer, events):
    peer.inject("no_reply", count=20)
    with pytest.raises(DeviceError, match=r"^attenuator: pos\? failed 3 times") as err:
        silent_wheel.position()
    assert err.value.unanswered
    assert kinds(events) == ["retry", "reconnect_failed", "retry", "reconnect_failed"]
