"""Modbus axis driver against the simulated controller over loopback TCP and RTU-over-socket."""

import threading
from types import SimpleNamespace

import pytest

from rig.config.rigfile import AxisConfig, RigConfig, SimulationConfig
from rig.core.errors import DeviceError
from rig.core.motion import move_time_s, position_at
from rig.drivers.interfaces import TwoAxisPositioner
from rig.drivers.modbus_axis import ModbusAxisController
from rig.drivers.modbus_axis_map import Status
from rig.drivers.retry import RetryPolicy
from rig.physics.brdf_models import get_model
from rig.simulators.modbus_axis_server import ModbusAxisServer
from rig.simulators.world import SimWorld

ARM = [(name, AxisConfig(limits_deg=(-180, 180), speed_deg_s=15, accel_deg_s2=30, settle_s=0.2))
       for name in ("arm_azimuth", "arm_polar")]
STAGE = [(name, AxisConfig(limits_deg=(-90, 90), speed_deg_s=10, accel_deg_s2=20, settle_s=0.2))
         for name in ("stage_vertical", "stage_normal")]
LASH = 0.001            # half the simulator's default backlash: the load lags the last travel by this


def make_world() -> SimWorld:
    """Repeatability noise off, so read-backs are exact (backlash stays)."""
    return SimWorld(RigConfig(simulation=SimulationConfig(positioning_sigma_deg=0.0, axis_zero_sigma_deg=0.0)),
                    get_model("lambert"), {"kd": 0.5})


def connect(url, world, name, axes, *, timeout_s=0.5):
    controller = ModbusAxisController(url, name=name, clock=world.clock, timeout_s=timeout_s,
                                      retry=RetryPolicy(attempts=3, backoff_s=0.05))
    events = []
    controller.events = lambda kind, **fields: events.append((kind, fields))
    return controller, events, [controller.axis(i, n, 1000.0, c.speed_deg_s, c.accel_deg_s2, c.settle_s)
                                for i, (n, c) in enumerate(axes)]


@pytest.fixture
def no_thread_leak():
    before = threading.active_count()
    yield
    assert threading.active_count() == before


def _rig(framer, timeout_s):
    world = make_world()
    server = ModbusAxisServer(world, ARM, framer=framer)
    controller, events, axes = connect(server.start(), world, "arm", ARM, timeout_s=timeout_s)
    return SimpleNamespace(world=world, server=server, controller=controller, events=events, axes=axes)


@pytest.fixture(params=["tcp", "rtu"])
def rig(request, no_thread_leak):
    r = _rig(request.param, timeout_s=0.5)
    yield r
    r.controller.close()
    r.server.stop()


@pytest.fixture
def faulty(request, no_thread_leak):
    """Short timeouts, so that injected silences cost little wall time; TCP unless parametrised."""
    r = _rig(getattr(request, "param", "tcp"), timeout_s=0.2)
    yield r
    r.controller.close()
    r.server.stop()


# -- driver against the simulated controller, TCP and RTU ------------------------------------
def test_move_wait_read_back(rig):
    azimuth, polar = rig.axes
    clock = rig.world.clock
    t0 = clock.now()
    TwoAxisPositioner("arm", azimuth, polar).move_to(30.0, -45.5)
    # one status poll each: the wait slept exactly the predicted time
    assert clock.now() - t0 == pytest.approx(azimuth.move_time_s(0, -45.5), abs=1e-5)
    assert azimuth.position_deg() == pytest.approx(30.0 - LASH, abs=1e-9)
    assert polar.position_deg() == pytest.approx(-45.5 + LASH, abs=1e-9)
    assert rig.world.axis_truth["arm_polar"]() == pytest.approx(-45.5 + LASH)
    assert azimuth.state().status == Status.READY | Status.IN_POSITION and not azimuth.is_moving()
    assert rig.events == []


def test_reads_follow_the_move_on_the_simulated_clock(rig):
    azimuth = rig.axes[0]
    azimuth.start_move(60.0)
    rig.world.clock.sleep(1.0)
    assert azimuth.is_moving()
    assert azimuth.position_deg() == pytest.approx(position_at(0.0, 60.0, 1.0, 15, 30) - LASH, abs=1e-3)
    azimuth.wait()
    assert azimuth.position_deg() == pytest.approx(60.0 - LASH)


def test_stop_halts_the_move(rig):
    azimuth = rig.axes[0]
    azimuth.start_move(90.0)
    rig.world.clock.sleep(2.0)
    azimuth.stop()
    azimuth.wait(timeout_s=1.0)
    assert not azimuth.is_moving()
    assert azimuth.position_deg() == pytest.approx(position_at(0.0, 90.0, 2.0, 15, 30) - LASH, abs=1e-3)


def test_home_runs_to_zero_and_sets_homed(rig):
    polar = rig.axes[1]
    polar.start_move(20.0)
    polar.wait()
    assert Status.HOMED not in polar.state().status
    t0 = rig.world.clock.now()
    polar.home()
    assert Status.HOMED in polar.state().status
    assert polar.position_deg() == pytest.approx(-LASH)
    run = move_time_s(20.0, 15, 30) + 0.2
    assert run + 0.5 <= rig.world.clock.now() - t0 <= run + 0.5 + polar.poll_s + 1e-6   # + sensor search


def test_identity(rig):
    assert rig.controller.identity().startswith("rig simulators SIM-2AX Modbus fw 1.0.0")
    assert rig.axes[1].identity().endswith("axis 1")


def test_target_beyond_soft_limits_is_an_alarm_until_reset(rig):
    azimuth = rig.axes[0]
    with pytest.raises(DeviceError, match=r"arm_azimuth: start move: alarm 0x67 \(software overtravel") as err:
        azimuth.start_move(200.0)
    assert not err.value.transient
    with pytest.raises(DeviceError, match="0x67"):
        azimuth.start_move(10.0)
    azimuth.reset_alarm()
    azimuth.start_move(10.0)
    azimuth.wait()
    assert azimuth.position_deg() == pytest.approx(10.0 - LASH)


# -- faults -----------------------------------------------------------------------------------
@pytest.mark.parametrize("faulty", ["tcp", "rtu"], indirect=True)
@pytest.mark.parametrize("fault", ["no_reply", "disconnect", "garbled"])
def test_transient_fault_is_retried_after_a_reconnect(faulty, fault):
    azimuth = faulty.axes[0]
    faulty.server.inject(fault)
    azimuth.start_move(10.0)
    azimuth.wait()
    assert azimuth.position_deg() == pytest.approx(10.0 - LASH)
    kinds = [kind for kind, _ in faulty.events]
    assert kinds == ["retry", "reconnect"]
    retry = faulty.events[0][1]
    assert retry["device"] == "arm_azimuth" and retry["what"] == "start move" and "0x0100" in retry["error"]


def test_exception_reply_is_a_persistent_error_naming_device_register_and_answer(faulty):
    faulty.server.inject("exception")
    with pytest.raises(DeviceError) as err:
        faulty.axes[0].position_deg()
    message = str(err.value)
    assert message.startswith("arm_azimuth: controller 'arm': read encoder position at register 0x010C")
    assert message.endswith("answered Modbus exception 4 (device failure)")
    assert not err.value.transient and faulty.events == []
    assert faulty.axes[0].position_deg() == pytest.approx(-LASH)            # one request only


def test_fault_can_target_one_axis(faulty):
    faulty.server.inject("exception", axis=1)
    assert faulty.axes[0].position_deg() == pytest.approx(-LASH)
    with pytest.raises(DeviceError, match="arm_polar: .* register 0x020C .* exception 4"):
        faulty.axes[1].position_deg()


def test_silence_outlasting_the_retries_is_persistent(faulty):
    faulty.server.inject("no_reply", count=3)
    with pytest.raises(DeviceError, match=r"read encoder position failed 3 times; last: .*0x010C.*no valid reply"):
        faulty.axes[0].position_deg()
    assert [kind for kind, _ in faulty.events] == ["retry", "reconnect"] * 2
    assert faulty.axes[0].position_deg() == pytest.approx(-LASH)


def test_alarm_during_a_move_names_code_and_meaning(faulty):
    azimuth = faulty.axes[0]
    faulty.server.inject("alarm", axis=0)
    azimuth.start_move(10.0)
    with pytest.raises(DeviceError, match=r"arm_azimuth: move: alarm 0x10 \(excessive position deviation"):
        azimuth.wait()
    azimuth.reset_alarm()
    azimuth.start_move(5.0)
    azimuth.wait()


def test_device_refusals_are_exception_replies(faulty):
    with pytest.raises(DeviceError, match=r"register 0x0108 .* exception 2 \(illegal address\)"):
        faulty.controller.write("arm", "write status", 0x0108, [0, 0])          # read-only register
    stalled = faulty.controller.axis(0, "arm_azimuth", 1000.0, 0.0, 30.0, 0.2)  # speed 0
    with pytest.raises(DeviceError, match=r"start move .* exception 3 \(illegal value\)"):
        stalled.start_move(10.0)


# -- life cycle and per-point cost ------------------------------------------------------------
def test_server_stops_cleanly_and_idempotently(no_thread_leak):
    world = make_world()
    server = ModbusAxisServer(world, ARM, framer="rtu")
    with server:
        assert server.url.startswith("modbus-rtu://socket://127.0.0.1:")
        controller, _, axes = connect(server.url, world, "arm", ARM)
        axes[0].position_deg()
    server.stop()
    with pytest.raises(DeviceError, match="failed 3 times"):
        controller.identity()
    controller.close()


def test_one_point_of_four_axes_on_two_controllers(no_thread_leak):
    """start + wait + read-back of 4 axes on two controllers, point after point (the protocol's wall
    time per point is a benchmark: benchmarks/paper_campaign.py)."""
    world = make_world()
    with ModbusAxisServer(world, ARM) as arm_server, ModbusAxisServer(world, STAGE) as stage_server:
        controllers, axes = [], []
        for url, name, cfg in ((stage_server.url, "stage", STAGE), (arm_server.url, "arm", ARM)):
            controller, _, these = connect(url, world, name, cfg)
            controllers.append(controller)
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
        for controller in controllers:
            controller.close()
