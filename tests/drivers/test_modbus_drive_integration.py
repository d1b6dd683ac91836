"""The Modbus drive driver (AZ map) against simulated Oriental Motor AZ drives over loopback TCP and
RTU-over-socket: moves, read-backs, homing, alarms and every injected fault."""

from types import SimpleNamespace

import pytest
from shared import ANSWERED_S, SILENCE_S

from rig.config.rigfile import AxisConfig, RigConfig, SimulationConfig
from rig.core.errors import DeviceError
from rig.core.motion import move_time_s, position_at
from rig.drivers.interfaces import TwoAxisPositioner
from rig.drivers.modbus_drive import ModbusDriveLink
from rig.drivers.modbus_drive_map import load_drive_map
from rig.drivers.retry import RetryPolicy
from rig.physics.brdf_models import get_model
from rig.simulators.oriental_az_peer import OrientalAZPeer
from rig.simulators.world import SimWorld

ARM = [(name, AxisConfig(limits_deg=(-180, 180), speed_deg_s=15, accel_deg_s2=30, settle_s=0.2))
       for name in ("arm_azimuth", "arm_polar")]
STAGE = [(name, AxisConfig(limits_deg=(-90, 90), speed_deg_s=10, accel_deg_s2=20, settle_s=0.2))
         for name in ("stage_vertical", "stage_normal")]
LASH = 0.001            # half the simulator's default backlash: the load lags the last travel by this
AZ = load_drive_map("oriental-az")


def make_world() -> SimWorld:
    """Repeatability noise off, so read-backs are exact (backlash stays)."""
    return SimWorld(RigConfig(simulation=SimulationConfig(positioning_sigma_deg=0.0, axis_zero_sigma_deg=0.0)),
                    get_model("lambert"), {"kd": 0.5})


def connect(url, world, name, axes, *, device_ids=(1, 2), timeout_s=ANSWERED_S):
    link = ModbusDriveLink(url, AZ, name=name, clock=world.clock, timeout_s=timeout_s,
                           retry=RetryPolicy(attempts=3, backoff_s=0.05))
    events = []
    link.events = lambda kind, **fields: events.append((kind, fields))
    return link, events, [link.axis(i, n, 1000.0, c.speed_deg_s, c.accel_deg_s2, c.settle_s)
                          for i, (n, c) in zip(device_ids, axes)]


def _rig(framer, timeout_s):
    world = make_world()
    peer = OrientalAZPeer(world, ARM, framer=framer)
    link, events, axes = connect(peer.start(), world, "arm", ARM, timeout_s=timeout_s)
    return SimpleNamespace(world=world, peer=peer, link=link, events=events, axes=axes)


@pytest.fixture(params=["tcp", "rtu"])
def rig(request, no_leaks):
    r = _rig(request.param, timeout_s=ANSWERED_S)
    yield r
    r.link.close()
    r.peer.stop()


@pytest.fixture
def faulty(request, no_leaks):
    """Short timeouts, so that injected silences cost little wall time; TCP unless parametrised."""
    r = _rig(getattr(request, "param", "tcp"), timeout_s=SILENCE_S)
    yield r
    r.link.close()
    r.peer.stop()


# -- driver against the simulated drives, TCP and RTU -------------------------------------------
def test_move_wait_read_back(rig):
    azimuth, polar = rig.axes
    clock = rig.world.clock
    arm = TwoAxisPositioner("arm", azimuth, polar)
    arm.move_to(-10.0, 10.0)                 # the first move starts from a read-back: it may cost a poll more
    t0 = clock.now()
    arm.move_to(30.0, -45.5)
    # one status poll each: the wait slept exactly the predicted time
    assert clock.now() - t0 == pytest.approx(azimuth.move_time_s(10.0, -45.5), abs=1e-5)
    assert azimuth.position_deg() == pytest.approx(30.0 - LASH, abs=1e-9)
    assert polar.position_deg() == pytest.approx(-45.5 + LASH, abs=1e-9)
    assert rig.world.axis_truth["arm_polar"]() == pytest.approx(-45.5 + LASH)
    state = azimuth.state()
    assert state.ready and state.in_position and not state.moving and not azimuth.is_moving()
    assert rig.events == []


def test_reads_follow_the_move_on_the_simulated_clock(rig):
    azimuth = rig.axes[0]
    azimuth.start_move(60.0)
    rig.world.clock.sleep(1.0)
    assert azimuth.is_moving() and not azimuth.state().ready
    assert azimuth.position_deg() == pytest.approx(position_at(0.0, 60.0, 1.0, 15, 30) - LASH, abs=1e-3)
    azimuth.wait()
    assert azimuth.position_deg() == pytest.approx(60.0 - LASH)


def test_a_new_move_replaces_the_one_under_way(rig):
    azimuth = rig.axes[0]
    azimuth.start_move(60.0)
    rig.world.clock.sleep(1.0)
    azimuth.start_move(-10.0)
    azimuth.wait()
    assert azimuth.position_deg() == pytest.approx(-10.0 + LASH)


def test_stop_halts_the_move(rig):
    azimuth = rig.axes[0]
    azimuth.start_move(90.0)
    rig.world.clock.sleep(2.0)
    azimuth.stop()
    rig.world.clock.sleep(0.3)
    assert not azimuth.is_moving()
    assert azimuth.position_deg() == pytest.approx(position_at(0.0, 90.0, 2.0, 15, 30) - LASH, abs=1e-3)


def test_home_returns_to_zero(rig):
    polar = rig.axes[1]
    polar.start_move(20.0)
    polar.wait()
    t0 = rig.world.clock.now()
    polar.home()
    assert polar.position_deg() == pytest.approx(-LASH)
    assert rig.world.clock.now() - t0 == pytest.approx(move_time_s(20.0, 15, 30) + 0.2, abs=1e-5)


def test_identity_names_drive_id_and_link(rig):
    assert rig.axes[1].identity() == f"Oriental Motor AZ series drive, Modbus id 2 at {rig.peer.url}"


def test_target_beyond_soft_limits_is_an_alarm_until_reset(rig):
    azimuth = rig.axes[0]
    azimuth.start_move(200.0)
    with pytest.raises(DeviceError, match=r"arm_azimuth: move: alarm 0x67 \(software overtravel") as err:
        azimuth.wait()
    assert not err.value.transient
    azimuth.start_move(10.0)                 # ignored while the alarm is present
    with pytest.raises(DeviceError, match="0x67"):
        azimuth.wait()
    azimuth.reset_alarm()
    azimuth.start_move(10.0)
    azimuth.wait()
    assert azimuth.position_deg() == pytest.approx(10.0 - LASH)


def test_out_of_range_operation_data_is_alarm_70(rig):
    azimuth = rig.axes[0]
    rig.link.write(1, "arm_azimuth", "start move", 0x0058, AZ.to_registers([0, 1, 10000, 0, 30000, 30000, 1000, 1]))
    with pytest.raises(DeviceError, match=r"alarm 0x70 \(operation data error"):        # speed 0
        azimuth.wait()


# -- faults -----------------------------------------------------------------------------------
@pytest.mark.parametrize("faulty", ["tcp", "rtu"], indirect=True)
@pytest.mark.parametrize("fault", ["no_reply", "disconnect", "garbled"])
def test_transient_fault_is_retried_after_a_reconnect(faulty, fault):
    azimuth = faulty.axes[0]
    azimuth.position_deg()
    faulty.peer.inject(fault)
    azimuth.start_move(10.0)
    azimuth.wait()
    assert azimuth.position_deg() == pytest.approx(10.0 - LASH)
    assert [kind for kind, _ in faulty.events] == ["retry", "reconnect"]
    retry = faulty.events[0][1]
    assert retry["device"] == "arm_azimuth" and retry["what"] == "start move" and "0x0058" in retry["error"]


def test_exception_reply_is_a_persistent_error_naming_drive_register_and_answer(faulty):
    faulty.peer.inject("exception")
    with pytest.raises(DeviceError) as err:
        faulty.axes[0].position_deg()
    message = str(err.value)
    assert message.startswith(f"arm_azimuth: Oriental Motor AZ series drive (Modbus id 1 at {faulty.peer.url}): "
                              "read feedback position at register 0x00CC")
    assert message.endswith("answered Modbus exception 0x04 (server device failure)")
    assert not err.value.transient and faulty.events == []
    assert faulty.axes[0].position_deg() == pytest.approx(-LASH)            # one request only


def test_fault_can_target_one_drive(faulty):
    faulty.peer.inject("exception", axis=1)
    assert faulty.axes[0].position_deg() == pytest.approx(-LASH)
    with pytest.raises(DeviceError, match=r"arm_polar: .*Modbus id 2 .* register 0x00CC .* exception 0x04"):
        faulty.axes[1].position_deg()


def test_silence_outlasting_the_retries_is_persistent(faulty):
    faulty.peer.inject("no_reply", count=3)
    with pytest.raises(DeviceError, match=r"read feedback position failed 3 times; last: .*0x00CC.*no valid reply"):
        faulty.axes[0].position_deg()
    assert [kind for kind, _ in faulty.events] == ["retry", "reconnect"] * 2
    assert faulty.axes[0].position_deg() == pytest.approx(-LASH)


def test_alarm_during_a_move_names_code_and_meaning(faulty):
    azimuth = faulty.axes[0]
    faulty.peer.inject("alarm", axis=0)
    azimuth.start_move(10.0)
    with pytest.raises(DeviceError, match=r"arm_azimuth: move: alarm 0x10 \(excessive position deviation"):
        azimuth.wait()
    azimuth.reset_alarm()
    azimuth.start_move(5.0)
    azimuth.wait()


def test_device_refusals_are_exception_replies(faulty):
    with pytest.raises(DeviceError, match=r"register 0x007E .* exception 0x02 \(illegal data address\)"):
        faulty.link.write(1, "arm", "write status", 0x007E, [0, 0])          # read-only register
    with pytest.raises(DeviceError, match=r"register 0x0120 .* exception 0x02 \(illegal data address\)"):
        faulty.link.read(1, "arm", "read", 0x0120, 2)                        # not served


@pytest.mark.parametrize("framer, gateway, last, timeout_s", [
    ("rtu", False, "no valid reply", 0.2),                    # an RS-485 bus: silence
    ("tcp", False, "no valid reply", 0.2),                    # a transparent converter: silence
    ("tcp", True, "exception 0x0B (gateway target device failed to respond)", 1.0),
])
def test_an_absent_drive_is_silence_or_a_gateways_0B_retried_then_one_message(no_leaks, framer, gateway, last,
                                                                             timeout_s):
    world = make_world()
    with OrientalAZPeer(world, ARM, framer=framer, gateway=gateway) as peer:
        link, events, axes = connect(peer.url, world, "arm", ARM, device_ids=(1, 9), timeout_s=timeout_s)
        with pytest.raises(DeviceError) as err:
            axes[1].position_deg()
        assert [kind for kind, _ in events] == ["retry", "reconnect"] * 2
        assert all(last in fields["error"] for kind, fields in events if kind == "retry")
        assert axes[0].position_deg() == pytest.approx(-LASH)         # the drive that is there still answers
        link.close()
    message = str(err.value)
    assert message.startswith("arm_polar: read feedback position failed 3 times; last: ")
    assert "Modbus id 9" in message and last in message and err.value.unanswered


def test_a_gateway_is_a_tcp_thing():
    with pytest.raises(ValueError, match="gateway=True is a Modbus/TCP gateway"):
        OrientalAZPeer(make_world(), ARM, framer="rtu", gateway=True)


# -- life cycle and per-point cost ------------------------------------------------------------
def test_peer_stops_cleanly_and_idempotently(no_leaks):
    world = make_world()
    peer = OrientalAZPeer(world, ARM, framer="rtu")
    with peer:
        assert peer.url.startswith("modbus-rtu://socket://127.0.0.1:")
        link, _, axes = connect(peer.url, world, "arm", ARM)
        axes[0].position_deg()
    peer.stop()
    with pytest.raises(DeviceError, match="failed 3 times"):
        axes[0].state()
    link.close()


def test_one_point_of_four_axes_on_two_links(no_leaks):
    """start + wait + read-back of 4 axes on two links, point after point (the protocol's wall time per point
    is a benchmark: benchmarks/per_point.py)."""
    world = make_world()
    with OrientalAZPeer(world, ARM) as arm_peer, OrientalAZPeer(world, STAGE, device_ids=(3, 4)) as stage_peer:
        links, axes = [], []
        for url, name, cfg, ids in ((stage_peer.url, "stage", STAGE, (3, 4)), (arm_peer.url, "arm", ARM, (1, 2))):
            link, _, these = connect(url, world, name, cfg, device_ids=ids)
            links.append(link)
            axes += these
        for i in range(40):
            sign = 1 if i % 2 else -1
            targets = (sign * 5.0, sign * 10.0, sign * 20.0, sign * 30.0)
            for axis, target in zip(axes, targets):
                axis.start_move(target)
            for axis in axes:
                axis.wait()
            # the load lags the last travel by the backlash; one encoder step is 0.001°
            assert [axis.position_deg() for axis in axes] == pytest.approx(targets, abs=LASH + 0.001)
        for link in links:
            link.close()
