"""P9710 optometer driver against its pty peer, with every fault; and the peer's life cycle."""

import os
import re
import threading
import time

import pytest

from rig.config.rigfile import MeterConfig, RigConfig, SimulationConfig
from rig.core.errors import DeviceError
from rig.drivers.p9710 import P9710
from rig.physics.brdf_models import get_model
from rig.simulators.faults import METER_FAULTS
from rig.simulators.p9710_peer import P9710Peer, range_for
from rig.simulators.world import SimWorld

CAL = 1.0e9
#: Each injectable fault and what the driver's error says the meter answered (a regex).
FAULT_REPLIES = pytest.mark.parametrize("fault, reply", [
    pytest.param("no_reply", re.escape("no complete reply to 'MA' within 0.2 s (got b'')"), id="no_reply"),
    pytest.param("garbled", re.escape("garbled reply to 'MA': b'\\x"), id="garbled"),
    pytest.param("short", re.escape("no complete reply to 'MA' within 0.2 s (got b'") + r"\d\.\d{4}E-06'\)",
                 id="short"),
    pytest.param("overrange", re.escape("overrange: 'MA' answered 'OVER'"), id="overrange"),
])


@pytest.fixture
def no_leaks():
    """Every pty, port and reader thread a test opened is closed by its end."""
    fds, threads = set(os.listdir("/proc/self/fd")), set(threading.enumerate())
    yield
    assert set(os.listdir("/proc/self/fd")) == fds
    assert set(threading.enumerate()) == threads


def lit_world(**sim) -> SimWorld:
    """A warm, steady lamp at nominal current."""
    cfg = RigConfig(meter=MeterConfig(calibration_lx_per_a=CAL),
                    simulation=SimulationConfig(**{"warmup_amplitude": 0.0, "drift_per_hour": 0.0, **sim}))
    world = SimWorld(cfg, get_model("lambert"), {"kd": 0.5})
    world.lamp.set_current(cfg.lamp.current_a, 0)
    world.lamp.switch(True)
    return world


@pytest.fixture
def world():
    return lit_world()


@pytest.fixture
def peer(world, no_leaks):
    with P9710Peer(world) as p:
        yield p


@pytest.fixture
def events():
    return []


def connect(path, world, events, cal=CAL) -> P9710:
    meter = P9710(path, calibration_lx_per_a=cal, clock=world.clock, timeout_s=0.2)
    meter.events = lambda kind, **fields: events.append((kind, fields))
    return meter


@pytest.fixture
def meter(peer, world, events):
    m = connect(peer.path, world, events)
    yield m
    m.close()


# -- driver against the simulated meter ----------------------------------------------------------

def test_identity_and_autorange_on_connect(meter, peer):
    assert meter.identity() == "Gigahertz-Optik P9710 V5.6 SN 97100042 detector VL-3701"
    assert peer.autorange


@pytest.mark.parametrize("driver_cal", [CAL, 1.02 * CAL])
def test_reading_is_photocurrent_times_configured_factor(events, no_leaks, driver_cal):
    """The factor comes from the driver's configuration; a wrong one scales the result."""
    world = lit_world(meter_noise_rel=0.0)
    with P9710Peer(world) as peer:
        meter = connect(peer.path, world, events, cal=driver_cal)
        reading = meter.read()
        meter.close()
    truth = world.illuminance_normal_lx()
    assert reading.calibration_lx_per_a == driver_cal
    assert reading.photocurrent_a == pytest.approx(truth / CAL, rel=1e-4)
    assert reading.illuminance_lx == pytest.approx(truth * driver_cal / CAL, rel=1e-4)


def test_readings_scatter_with_the_configured_noise(meter, world):
    deviations = []
    for _ in range(50):
        reading = meter.read()
        deviations.append(reading.illuminance_lx / world.illuminance_normal_lx() - 1)
    noise = world.config.simulation.meter_noise_rel
    mean = sum(deviations) / len(deviations)
    std = (sum((d - mean) ** 2 for d in deviations) / (len(deviations) - 1)) ** 0.5
    assert abs(mean) < 4 * noise / len(deviations) ** 0.5
    assert 0.6 * noise < std < 1.4 * noise


def test_autorange_follows_a_jump_with_one_transient_overrange(meter, world, events):
    world.lamp.set_current(0.2 * world.config.lamp.current_a, 0)
    dim = meter.read()
    assert meter.measuring_range() == range_for(dim.photocurrent_a) == 4
    assert events == []
    world.lamp.set_current(world.config.lamp.current_a, 0)
    bright = meter.read()
    assert bright.illuminance_lx == pytest.approx(world.illuminance_normal_lx(), rel=0.01)
    assert meter.measuring_range() == range_for(bright.photocurrent_a) == 2
    assert [kind for kind, _ in events] == ["retry", "reconnect"]
    assert events[0][1]["error"] == "meter: overrange: 'MA' answered 'OVER'"


def test_reconnect_restores_a_forgotten_autorange(meter, peer, world, events):
    """A power-cycled meter holds its range; the reconnect after the overrange sends SB1 again."""
    peer.autorange, peer.range = False, 7
    assert meter.read().illuminance_lx == pytest.approx(world.illuminance_normal_lx(), rel=0.01)
    assert peer.autorange
    assert [kind for kind, _ in events] == ["retry", "reconnect", "retry", "reconnect"]


def test_current_beyond_the_top_range_is_a_persistent_error(world, events, no_leaks):
    with P9710Peer(world, responsivity_a_per_lx=1e-6) as peer:    # 5 mA: beyond 2 mA full scale
        meter = connect(peer.path, world, events)
        with pytest.raises(DeviceError, match=r"^meter: MA failed 3 times; last: meter: overrange: "
                                              r"'MA' answered 'OVER'$") as err:
            meter.read()
        meter.close()
    assert not err.value.transient


@FAULT_REPLIES
def test_each_fault_costs_one_retry(meter, peer, world, events, fault, reply):
    peer.inject(fault)
    assert meter.read().illuminance_lx == pytest.approx(world.illuminance_normal_lx(), rel=0.01)
    (retry, retry_fields), (reconnect, _) = events
    assert (retry, reconnect) == ("retry", "reconnect")
    assert retry_fields["what"] == "MA" and re.match(f"meter: {reply}", retry_fields["error"])


@FAULT_REPLIES
def test_a_lasting_fault_is_a_clean_persistent_error(meter, peer, world, events, fault, reply):
    peer.inject(fault, count=3)
    with pytest.raises(DeviceError) as err:
        meter.read()
    assert re.match(f"meter: MA failed 3 times; last: meter: {reply}", str(err.value))
    assert err.value.device == "meter" and not err.value.transient
    assert [kind for kind, _ in events] == ["retry", "reconnect"] * 2
    assert meter.read().illuminance_lx == pytest.approx(world.illuminance_normal_lx(), rel=0.01)


def test_reading_costs_rig_time_not_wall_time(meter, world, monkeypatch):
    """The 0.2 s integrations are slept on the rig clock; nothing in the driver or peer sleeps in wall time."""
    wall_sleeps = []
    monkeypatch.setattr(time, "sleep", wall_sleeps.append)
    t_rig = world.clock.now()
    for _ in range(20):
        meter.read()
    assert world.clock.now() - t_rig == pytest.approx(20 * 0.2)
    assert wall_sleeps == []


# -- the peer itself -----------------------------------------------------------------------------

def test_peer_lifecycle(world, no_leaks):
    peer = P9710Peer(world)
    path = peer.start()
    assert path.startswith("/dev/pts/") and os.path.exists(path)
    with pytest.raises(RuntimeError, match="already started"):
        peer.start()
    peer.stop()
    peer.stop()
    with pytest.raises(ValueError, match="unknown fault 'smoke'"):
        peer.inject("smoke")
    assert set(METER_FAULTS.names) == {"no_reply", "garbled", "short", "overrange"}
