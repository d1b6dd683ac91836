"""Modbus RTU for the tests that replay captured frames byte for byte (the drive driver's and the simulated AZ
drive's) and for the vendors' RTU clients: the CRC every RTU frame ends with, and a serial port on the peer."""

from __future__ import annotations

import os
import select
import socket
import threading
import tty
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field


def crc16_modbus(data: bytes) -> bytes:
    """CRC-16/MODBUS (poly 0xA001 reflected, init 0xFFFF), low byte first, as an RTU frame carries it."""
    crc = 0xFFFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = (crc >> 1) ^ 0xA001 if crc & 1 else crc >> 1
    return crc.to_bytes(2, "little")


@dataclass
class SerialLine:
    """A pseudo-terminal in front of the peer: `path` is the serial device a client opens; `sent` and `received`
    are the bytes that went to the peer and came back, as they crossed the line."""

    path: str
    sent: bytearray = field(default_factory=bytearray)
    received: bytearray = field(default_factory=bytearray)


@contextmanager
def serial_line(peer_url: str) -> Iterator[SerialLine]:
    """A serial device path whose far end is an RTU peer listening on `modbus-rtu://socket://host:port`:
    a client that opens a port by name (minimalmodbus) reaches the peer as it would over an RS-485 adapter."""
    host, _, port = peer_url.removeprefix("modbus-rtu://socket://").rpartition(":")
    master, slave = os.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    line = SerialLine(os.ttyname(slave))
    done = threading.Event()
    with socket.create_connection((host, int(port)), timeout=5.0) as peer:
        def pump() -> None:
            while not done.is_set():
                ready, _, _ = select.select([master, peer], [], [], 0.02)
                if master in ready:
                    data = os.read(master, 4096)
                    line.sent += data
                    peer.sendall(data)
                if peer in ready:
                    data = peer.recv(4096)
                    if not data:
                        return
                    line.received += data
                    os.write(master, data)

        thread = threading.Thread(target=pump, name="serial-line", daemon=True)
        thread.start()
        try:
            yield line
        finally:
            done.set()
            thread.join(timeout=5.0)
            os.close(master)
            os.close(slave)            # kept open until now: a pty whose slave closes hangs up the master
