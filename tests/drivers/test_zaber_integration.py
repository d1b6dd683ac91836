"""Zaber ASCII driver against the rebuilt chain peer over loopback TCP and a pty, with every fault; the peer's own
answers, byte for byte.

Provenance of the peer replays: the Zaber article's constructed examples (zaber.com/articles/ascii-protocol:
`/1 home` → `@01 0 OK BUSY -- 0`, `/1` → `@01 0 OK IDLE -- 0`, `/1 0 move abs 10000` → `@01 0 OK BUSY -- 0`,
`/1 0 get pos` → `@01 0 OK IDLE -- 12345`), the ASCII protocol manual (`RJ` reasons, `warnings`, message ids,
CRLF replies, checksums on replies) and github stphnt/zproto checksum tests (`/1:CF`, `/1 tools echo:BF`).
The article's `/1 0 home` → `RJ … BADCOMMAND` contradicts its own `/1 home` → `OK` (axis 0 is the whole device)
and is not replayed.
"""

import re
import socket
from types import SimpleNamespace

import pytest
import serial
from shared import ANSWERED_S, SILENCE_S
from shared import ZABER_CONNECT as CONNECT

from rig.config.rigfile import AxisConfig, RigConfig, SimulationConfig
from rig.core.errors import DeviceError
from rig.drivers.retry import RetryPolicy
from rig.drivers.zaber import ZaberChain, lrc
from rig.physics.brdf_models import get_model
from rig.simulators.faults import ZABER_FAULTS, PeerFaults
from rig.simulators.world import SimWorld
from rig.simulators.zaber_peer import CYCLE_DIST, ZaberPeer

ARM = {"arm_azimuth": AxisConfig(limits_deg=(-180, 180), speed_deg_s=15, accel_deg_s2=30, settle_s=0.2),
       "arm_polar": AxisConfig(limits_deg=(-90, 90), speed_deg_s=15, accel_deg_s2=30, settle_s=0.2)}
CHAIN = [(1, 1, "arm_azimuth", ARM["arm_azimuth"]), (2, 1, "arm_polar", ARM["arm_polar"])]
STEP = 360 / CYCLE_DIST
LASH = 0.001            # half the model's default backlash: the load (its encoder) lags the last travel by this
HALF = STEP / 2         # `get pos` reads the microstep nearest the target, exactly


def make_world() -> SimWorld:
    """Repeatability noise off, so read-backs are exact up to backlash and the microstep."""
    return SimWorld(RigConfig(simulation=SimulationConfig(positioning_sigma_deg=0.0, axis_zero_sigma_deg=0.0)),
                    get_model("lambert"), {"kd": 0.5})



def connect(peer, world, events, timeout_s=ANSWERED_S, **options):
    arm = ZaberChain.from_rig(clock=world.clock, settings=ARM, name="arm", address=peer.url, timeout_s=timeout_s,
                              **options)
    arm.axes[0].controller.retry = RetryPolicy(attempts=3, backoff_s=0.05)
    arm.axes[0].controller.events = lambda kind, **fields: events.append((kind, fields))
    return arm


def homed_chain(medium, timeout_s):
    world, events = make_world(), list[tuple[str, dict]]()
    with ZaberPeer(world, CHAIN, medium=medium) as peer:
        arm = connect(peer, world, events, timeout_s, home=True)
        yield SimpleNamespace(world=world, peer=peer, arm=arm, events=events)
        arm.close()


@pytest.fixture(params=["tcp", "pty"])
def rig(request, no_leaks):
    yield from homed_chain(request.param, ANSWERED_S)


@pytest.fixture(params=["tcp", "pty"])
def silent_rig(request, no_leaks):
    """The chain with lost replies timing out quickly (SILENCE_S)."""
    yield from homed_chain(request.param, SILENCE_S)


def test_home_move_wait_read_back(rig):
    azimuth, polar = rig.arm.axes
    clock = rig.world.clock
    t0 = clock.now()
    rig.arm.move_to(30.0, -45.5)
    assert clock.now() - t0 == pytest.approx(polar.move_time_s(0, -45.5), abs=1e-5)   # no poll beyond one
    assert azimuth.position_deg() == pytest.approx(30.0, abs=HALF)
    assert polar.position_deg() == pytest.approx(-45.5, abs=HALF)
    assert rig.world.axis_truth["arm_azimuth"]() == pytest.approx(30.0 - LASH, abs=1e-9)   # the load lags
    assert not azimuth.is_moving() and rig.events == []


def test_is_moving_and_stop(rig):
    azimuth = rig.arm.axes[0]
    azimuth.start_move(90.0)
    rig.world.clock.sleep(1.0)
    assert azimuth.is_moving()
    azimuth.stop()
    rig.world.clock.sleep(0.3)
    assert not azimuth.is_moving()
    stopped = azimuth.position_deg()
    assert 0 < stopped < 90
    azimuth.start_move(0.0)                     # from an unknown point: the driver reads it first
    azimuth.wait()
    assert azimuth.position_deg() == pytest.approx(0.0, abs=HALF)


def test_power_up_axes_refuse_moves_until_homed(no_leaks):
    world, events = make_world(), list[tuple[str, dict]]()
    with ZaberPeer(world, CHAIN) as peer:
        arm = connect(peer, world, events)
        try:
            assert [a.homed for a in arm.axes] == [False, False]
            with pytest.raises(DeviceError, match="has no reference position .*: home it before moving"):
                arm.start_move(10.0, 10.0)
            arm.home()
            arm.move_to(10.0, 10.0)
            assert arm.positions_deg() == pytest.approx((10.0, 10.0), abs=HALF)
        finally:
            arm.close()


@pytest.mark.parametrize("fault, flag, meaning", [("stall", "FS", "stalled and stopped"),
                                                  ("limit", "WL", "unexpected limit trigger")])
def test_a_stall_or_limit_ends_the_move_in_a_persistent_error(rig, fault, flag, meaning):
    polar = rig.arm.axes[1]
    rig.peer.inject(fault, axis="arm_polar")
    polar.start_move(20.0)
    with pytest.raises(DeviceError) as err:
        polar.wait()
    assert re.fullmatch(f"arm_polar: status poll: device 2 axis 1 on {re.escape(rig.peer.url)} flags {flag} "
                        f"\\({meaning}\\); `warnings clear` after fixing the cause", str(err.value))
    assert not err.value.transient
    with pytest.raises(DeviceError, match=f"move abs 0.* flags {flag}"):
        polar.start_move(0.0)                     # the flag stays until cleared
    assert polar.clear_warnings() == (flag,)
    polar.start_move(0.0)
    polar.wait()
    assert polar.position_deg() == pytest.approx(0.0, abs=HALF)


def test_a_target_beyond_the_limits_is_rejected(rig):
    with pytest.raises(DeviceError, match=r"^arm_polar: '/2 1 move abs 426667:..' rejected: BADDATA \(parameter "
                                          r"missing or out of range\)$") as err:
        rig.arm.axes[1].start_move(100.0)
    assert not err.value.transient


def inject(peer, fault, count=1):
    if fault == "disconnect" and peer.medium == "pty":
        with pytest.raises(ValueError, match="a pty cannot be disconnected"):
            peer.inject(fault)
        pytest.skip("a pty has no connection to drop")
    peer.inject(fault, count)


@pytest.mark.parametrize("fault", ZABER_FAULTS.transient)
def test_each_transient_fault_costs_one_retry(silent_rig, fault):
    inject(silent_rig.peer, fault)
    assert silent_rig.arm.axes[0].position_deg() == pytest.approx(0.0, abs=HALF)         # homed
    assert [kind for kind, _ in silent_rig.events] == ["retry", "reconnect"]
    silent_rig.arm.move_to(5.0, 5.0)


@pytest.mark.parametrize("fault", ZABER_FAULTS.transient)
def test_a_lasting_fault_is_a_clean_persistent_error(silent_rig, fault):
    inject(silent_rig.peer, fault, count=3)
    with pytest.raises(DeviceError, match=r"^arm_azimuth: /1 1 get pos:AC failed 3 times; last: ") as err:
        silent_rig.arm.axes[0].position_deg()
    assert err.value.unanswered and not err.value.transient
    assert [kind for kind, _ in silent_rig.events] == ["retry", "reconnect"] * 2
    silent_rig.arm.move_to(5.0, 5.0)                    # the link recovers


def test_a_device_without_cycle_distance_uses_the_configured_microstep_size(no_leaks):
    world, events = make_world(), list[tuple[str, dict]]()
    with ZaberPeer(world, CHAIN, answers_cycle_dist=False, homed=True) as peer:
        arm = connect(peer, world, events, microsteps_per_degree=CYCLE_DIST / 360, checksum=False)
        arm.move_to(12.0, -3.0)
        assert arm.positions_deg() == pytest.approx((12.0, -3.0), abs=HALF)
        arm.close()


# -- the peer itself, byte for byte ------------------------------------------------------------------
@pytest.fixture
def exchange(no_leaks):
    """`exchange(request) -> reply lines`: raw bytes to and from a homed, backlash-free peer over TCP."""
    world = make_world()
    with ZaberPeer(world, [(1, 1, "x", ARM["arm_azimuth"]), (2, 1, "y", ARM["arm_polar"])], homed=True,
                   backlash_deg=0.0) as peer:
        host, port = peer.url.removeprefix("socket://").split(":")
        with socket.create_connection((host, int(port)), timeout=1.0) as sock, sock.makefile("rb") as replies:
            def one(request: bytes, lines: int = 1) -> bytes:
                sock.sendall(request)
                return b"".join(replies.readline() for _ in range(lines))
            one.world, one.peer = world, peer          # type: ignore[attr-defined]
            yield one


def test_the_articles_examples(exchange):
    assert exchange(b"/1 home\n") == b"@01 0 OK BUSY -- 0\r\n"
    exchange.world.clock.sleep(1.0)
    assert exchange(b"/1\n") == b"@01 0 OK IDLE -- 0\r\n"
    assert exchange(b"/1 0 move abs 10000\n") == b"@01 0 OK BUSY -- 0\r\n"
    assert exchange(b"/1 0 move abs 12345\n") == b"@01 0 OK BUSY -- 0\r\n"
    exchange.world.clock.sleep(1.0)
    assert exchange(b"/1 0 get pos\n") == b"@01 0 OK IDLE -- 12345\r\n"


def test_the_drivers_connect_script(exchange):
    for request, reply in CONNECT:
        assert exchange(request) == reply


def test_checksummed_requests_get_checksummed_replies(exchange):
    reply = exchange(b"/1:CF\n")
    assert reply == b"@01 0 OK IDLE -- 0:" + lrc("01 0 OK IDLE -- 0").encode() + b"\r\n"
    echoed = "01 0 OK IDLE -- 0"
    assert exchange(b"/1 tools echo:BF\n") == f"@{echoed}:{lrc(echoed)}\r\n".encode()
    exchange(b"/1:00\n", lines=0)                  # a wrong checksum: no answer ...
    assert exchange(b"/2 1 get accel\n") == b"@02 1 OK IDLE -- 21\r\n"      # ... and the next request is fine


@pytest.mark.parametrize("request_, reply", [
    (b"/1 1 fly\n", b"@01 1 RJ IDLE -- BADCOMMAND\r\n"),
    (b"/1 1 move abs ten\n", b"@01 1 RJ IDLE -- BADDATA\r\n"),
    (b"/1 1 move abs 999999999\n", b"@01 1 RJ IDLE -- BADDATA\r\n"),
    (b"/1 3 get pos\n", b"@01 3 RJ IDLE -- BADAXIS\r\n"),
    (b"/1 1 set maxspeed 0\n", b"@01 1 RJ IDLE -- BADDATA\r\n"),
    (b"/1 1 home now\n", b"@01 1 RJ IDLE -- BADDATA\r\n"),
    (b"/1 1 7 get limit.cycle.dist\r\n", b"@01 1 7 OK IDLE -- 1536000\r\n"),        # a message id, CRLF
    (b"/2 1 warnings\n", b"@02 1 OK IDLE -- 00\r\n"),
], ids=lambda v: v.decode().strip() if isinstance(v, bytes) else v)
def test_answers(exchange, request_, reply):
    assert exchange(request_) == reply


def test_broadcast_is_answered_by_every_device_and_strangers_by_none(exchange):
    assert exchange(b"/get maxspeed\n", lines=2) == b"@01 0 OK IDLE -- 104858\r\n@02 0 OK IDLE -- 104858\r\n"
    exchange(b"/7 1 get pos\n", lines=0)
    assert exchange(b"/2 0 get pos\n") == b"@02 0 OK IDLE -- 0\r\n"


def test_power_up_reference_and_injected_flags(no_leaks):
    world = make_world()
    with ZaberPeer(world, CHAIN, medium="pty") as peer, serial.Serial(peer.url, 115200, timeout=1) as port:
        def one(request: bytes) -> bytes:
            port.write(request)
            return port.read_until(b"\n")
        assert one(b"/1 1 warnings\n") == b"@01 1 OK IDLE WR 01 WR\r\n"
        assert one(b"/1 1 home\n") == b"@01 1 OK BUSY WR 0\r\n"
        world.clock.sleep(1.0)
        assert one(b"/1 1\n") == b"@01 1 OK IDLE -- 0\r\n"
        peer.inject("stall", axis="arm_azimuth")
        assert one(b"/1 1 move abs 4266\n") == b"@01 1 OK BUSY -- 0\r\n"
        world.clock.sleep(2.0)
        assert one(b"/1 1 warnings clear\n") == b"@01 1 OK IDLE FS 01 FS\r\n"
        assert one(b"/1 1 warnings\n") == b"@01 1 OK IDLE -- 00\r\n"


def test_peer_names_its_faults():
    assert ZABER_FAULTS == PeerFaults(("no_reply", "garbled", "short", "disconnect"), ("stall", "limit"))
