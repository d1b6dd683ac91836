"""ServedCamera: byte-exact exchanges with a scripted peer, every failure, and against the CameraServer.

The protocol is ours (docs/sim-camera-protocol.md). The replay fixture's port returns whole
replies and has no read of a byte count, which a binary frame needs; the script here is a
loopback peer that fails on any byte the driver sends out of turn.
"""

import json
import socket
import threading
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import asdict

import numpy as np
import pytest
from shared import ANSWERED_S
from sim_worlds import lit_world

from rig.config.rigfile import RigConfig
from rig.core.errors import DeviceError
from rig.core.values import Window
from rig.drivers.sim_camera import ServedCamera, parse_address
from rig.drivers.wallclock import WallClock
from rig.simulators.camera import SimCamera
from rig.simulators.camera_server import CameraServer
from rig.simulators.clock import SimClock

SENSOR = RigConfig().camera.sensor_info()
OPENING = [(b"HELLO rig-sim-camera/1\n", b"OK rig-sim-camera/1 scripted camera\n"),
           (b"SENSOR?\n", b"OK " + json.dumps(asdict(SENSOR)).encode() + b"\n")]


@contextmanager
def scripted_peer(exchanges: Sequence[tuple[bytes, bytes | None]],
                  hang_up: bool = False) -> Iterator[tuple[str, list[bytes]]]:
    """A loopback peer answering each expected request line with its scripted bytes (None: no answer),
    then waiting for the driver to hang up (or, `hang_up`, closing at once); yields its address and the
    lines it received, and checks on leaving that the driver sent exactly the script's requests."""
    listener = socket.create_server(("127.0.0.1", 0))
    received: list[bytes] = []

    def serve() -> None:
        conn, _ = listener.accept()
        with conn, conn.makefile("rb") as lines:
            for expected, reply in exchanges:
                line = lines.readline()
                received.append(line)
                if line != expected or reply is None:
                    lines.read()                      # until the driver closes
                    return
                conn.sendall(reply)
            if not hang_up:
                received.extend(lines.readlines())    # anything more is a failure below

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield f"socket://127.0.0.1:{listener.getsockname()[1]}", received
        thread.join(5.0)
        assert not thread.is_alive(), "the driver did not hang up"
        assert received == [request for request, _ in exchanges], received
    finally:
        listener.close()


def test_address_must_be_socket_host_port():
    assert parse_address("socket://127.0.0.1:5025") == ("127.0.0.1", 5025)
    for bad in ("tcp://127.0.0.1:5025", "socket://127.0.0.1", "socket://:80", "socket://host:port"):
        with pytest.raises(ValueError, match="is not socket://host:port"):
            parse_address(bad)
    with pytest.raises(DeviceError, match="camera: camera address '/dev/ttyUSB0' is not socket://host:port"):
        ServedCamera("/dev/ttyUSB0", clock=SimClock())


def test_capture_is_expose_sleep_read_byte_for_byte():
    clock = SimClock()
    pixels = np.array([[1, 2, 3], [256, 4095, 0x0A0D]], dtype=np.uint16)   # a LF and a CR in the data
    exchanges = [*OPENING,
                 (b"EXPOSE 0.25 0 10 20 3 2\n", b"OK 0.2500004\n"),
                 (b"READ\n", b"OK FRAME 3 2 0.25 7.5 0 12\n" + pixels.astype("<u2").tobytes()),
                 (b"EXPOSE 15.0 1 0 0 1390 1040\n", b"OK 15.1\n"),
                 (b"READ\n", b"OK FRAME 1390 1040 15.0 7.75 1 2891200\n" + bytes(2891200)),
                 (b"BYE\n", b"OK\n")]
    with scripted_peer(exchanges) as (address, _):
        cam = ServedCamera(address, clock=clock)
        assert cam.identity() == "scripted camera" and cam.sensor == SENSOR
        frame = cam.capture(0.25, Window(10, 20, 3, 2))
        assert clock.now() == pytest.approx(0.2500004, abs=1e-12)
        np.testing.assert_array_equal(frame.pixels_dn, pixels)
        assert frame.pixels_dn.dtype == np.uint16 and frame.exposure_s == 0.25
        assert frame.window == Window(10, 20, 3, 2) and not frame.dark and frame.meta == {"start_s": 7.5}
        dark = cam.capture_dark(15.0)
        assert dark.dark and dark.pixels_dn.shape == (1040, 1390) and dark.window == cam.full_window()
        assert clock.now() == pytest.approx(15.3500004, abs=1e-9)
        cam.close()
        cam.close()                                                       # twice is fine
    with pytest.raises(DeviceError, match="the camera was closed"):
        cam.capture(0.1)


def test_keep_alives_run_while_the_client_sleeps_the_exposure():
    clock = SimClock()
    fed = []
    clock.keep_alive(1.0, lambda: fed.append(clock.now()))
    exchanges = [*OPENING, (b"EXPOSE 10.0 0 0 0 1 1\n", b"OK 10.0\n"),
                 (b"READ\n", b"OK FRAME 1 1 10.0 0.0 0 2\n\x40\x00"), (b"BYE\n", b"OK\n")]
    with scripted_peer(exchanges) as (address, _):
        cam = ServedCamera(address, clock=clock)
        cam.capture(10.0, Window(0, 0, 1, 1))
        cam.close()
    assert fed == pytest.approx([1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0])


READ_FAILURES = pytest.mark.parametrize("reply, message, transient", [
    (b"OK FRAME 2 2 0.1 0.0 0 8\n\x01\x00\x02\x00", r"short frame: 4 of 8 bytes of pixels within 0.3 s", True),
    (b"OK FRAME 2 2 fast 0.0 0 8\n", r"malformed frame header 'FRAME 2 2 fast 0.0 0 8'", False),
    (b"OK FRAME 2 2 0.1 0.0\n", r"malformed frame header 'FRAME 2 2 0.1 0.0'", False),
    (b"OK FRAME 3 2 0.1 0.0 0 12\n", r"frame header 'FRAME 3 2 0.1 0.0 0 12' does not match the exposure", False),
    (b"OK FRAME 2 2 0.1 0.0 1 8\n", r"frame header .* does not match the exposure of .* \(dark 0\)", False),
    (b"ERR READ without an exposure: send EXPOSE first\n",
     r"refused 'READ': READ without an exposure: send EXPOSE first", False),
    (b"NOPE\n", r"answered 'READ' with 'NOPE', neither OK nor ERR", True),
    (b"OK FRA", r"connection closed before the reply to 'READ' \(got b'OK FRA'\)", True),
    (None, r"no reply to 'READ' within 0.3 s", True),
], ids=["short", "not-a-number", "fields", "size", "dark", "err", "garbage", "cut", "timeout"])


@READ_FAILURES
def test_every_read_failure_is_a_device_error_naming_the_address(reply, message, transient):
    exchanges = [*OPENING, (b"EXPOSE 0.1 0 0 0 2 2\n", b"OK 0.1\n"), (b"READ\n", reply)]
    if reply is not None and reply.startswith(b"ERR"):
        exchanges.append((b"BYE\n", b"OK\n"))                       # the session goes on, closed politely
    with scripted_peer(exchanges, hang_up=reply == b"OK FRA") as (address, _):
        # the timeout the two lost replies (short, timeout) run out; long where every byte comes (ANSWERED_S)
        cam = ServedCamera(address, clock=SimClock(), timeout_s=0.3 if "within 0.3 s" in message else ANSWERED_S)
        with pytest.raises(DeviceError, match=f"camera: served camera at {address}: {message}") as err:
            cam.capture(0.1, Window(0, 0, 2, 2))
        assert err.value.transient is transient
        cam.close()


@pytest.mark.parametrize("reply, message", [
    (b"OK soon\n", r"answered 'EXPOSE 0.1 0 0 0 2 2' with 'soon', not a duration in seconds"),
    (b"OK -1\n", r"answered 'EXPOSE 0.1 0 0 0 2 2' with '-1', not a duration in seconds"),
    (b"ERR window Window(x0=0, y0=0, width=2, height=2) is not inside Window(x0=0, y0=0, width=1, height=1)\n",
     r"refused 'EXPOSE 0.1 0 0 0 2 2': window Window\(x0=0"),
])
def test_a_refused_or_odd_exposure_is_a_persistent_device_error(reply, message):
    exchanges = [*OPENING, (b"EXPOSE 0.1 0 0 0 2 2\n", reply), (b"BYE\n", b"OK\n")]
    with scripted_peer(exchanges) as (address, _):
        cam = ServedCamera(address, clock=SimClock())
        with pytest.raises(DeviceError, match=message) as err:
            cam.capture(0.1, Window(0, 0, 2, 2))
        assert not err.value.transient
        cam.close()


def test_a_peer_speaking_another_protocol_or_a_bad_sensor_is_refused():
    with scripted_peer([(b"HELLO rig-sim-camera/1\n", b"OK rig-sim-camera/2 future\n")]) as (address, _):
        with pytest.raises(DeviceError, match="answered HELLO with 'rig-sim-camera/2 future', not rig-sim-camera/1"):
            ServedCamera(address, clock=SimClock())
    with scripted_peer([OPENING[0], (b"SENSOR?\n", b'OK {"width_px": 3}\n')]) as (address, _):
        with pytest.raises(DeviceError, match="malformed SENSOR\\? reply"):
            ServedCamera(address, clock=SimClock())


def test_nothing_listening_is_a_transient_error_naming_the_address():
    with socket.create_server(("127.0.0.1", 0)) as placeholder:
        address = f"socket://127.0.0.1:{placeholder.getsockname()[1]}"
    with pytest.raises(DeviceError, match=f"served camera at {address}: cannot connect") as err:
        ServedCamera(address, clock=SimClock())
    assert err.value.transient


# --- against the served simulated camera --------------------------------------------------------


def test_served_frames_are_the_in_process_cameras_frames():
    """Same seed, same calls: the served camera's frames, times and clock are the in-process camera's."""
    local_world, served_world = lit_world(), lit_world()
    local = SimCamera(local_world)
    calls = [("capture", np.float64(0.002), Window.centred(1390, 1040, 100, 100)),
             ("capture_dark", 0.5, Window(17, 900, 64, 40)), ("capture", 1e-6, None),
             ("capture", 100.0, Window(0, 0, 5, 7))]
    with CameraServer(served_world) as server:
        assert server.url is not None
        served = ServedCamera(server.url, clock=served_world.clock)
        assert served.sensor == local.sensor and served.identity() == local.identity()
        for method, exposure, window in calls:
            a, b = getattr(local, method)(exposure, window), getattr(served, method)(exposure, window)
            assert np.array_equal(a.pixels_dn, b.pixels_dn) and b.pixels_dn.dtype == np.uint16
            assert (a.exposure_s, a.window, a.dark) == (b.exposure_s, b.window, b.dark)
            assert b.meta["start_s"] == pytest.approx(a.meta["start_s"], abs=1e-9)
            assert served_world.clock.now() == pytest.approx(local_world.clock.now(), abs=1e-9)
        with pytest.raises(DeviceError, match="is not inside"):
            served.capture(0.1, Window(1300, 0, 100, 10))
        served.close()


def test_a_second_client_of_the_served_camera_is_told_the_rig_is_in_use():
    world = lit_world()
    with CameraServer(world) as server:
        assert server.url is not None
        first = ServedCamera(server.url, clock=world.clock)
        with pytest.raises(DeviceError, match="the served rig is in use by another client") as err:
            ServedCamera(server.url, clock=world.clock)
        assert not err.value.transient
        first.capture(0.01, Window(0, 0, 4, 4))                          # the first goes on
        first.close()
        ServedCamera(server.url, clock=world.clock).close()               # and then the camera is free


def test_a_dropped_connection_is_reopened_by_the_next_capture():
    world = lit_world()
    with CameraServer(world) as server:
        assert server.url is not None
        cam = ServedCamera(server.url, clock=world.clock)
        assert cam._sock is not None
        cam._sock.shutdown(socket.SHUT_RDWR)                              # the link drops
        with pytest.raises(DeviceError, match="connection lost during 'EXPOSE 0.01 0 0 0 4 4'") as err:
            cam.capture(0.01, Window(0, 0, 4, 4))
        assert err.value.transient
        assert cam.capture(0.01, Window(0, 0, 4, 4)).pixels_dn.shape == (4, 4)   # what a retry does
        cam.close()


def test_on_a_served_world_the_frame_comes_after_exposure_and_readout_on_the_world_clock():
    world = lit_world(WallClock(scale=50))
    with CameraServer(world) as server:
        assert server.url is not None
        cam = ServedCamera(server.url, clock=WallClock(scale=50))
        window = Window(0, 0, 139, 104)
        frame = cam.capture(2.0, window)
        assert world.clock.now() >= frame.meta["start_s"] + 2.0 + world.config.camera.readout_s / 100
        assert frame.pixels_dn.shape == (104, 139) and frame.exposure_s == 2.0
        cam.close()
