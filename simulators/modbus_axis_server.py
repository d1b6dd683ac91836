"""Protocol peer of `rig.drivers.modbus_axis`: a simulated two-axis controller on loopback.

A pymodbus 3.16 server (SimDevice) in a background thread with its own event
loop serves the register map of docs/modbus-axis-register-map.md (the data in
`rig.drivers.modbus_axis_map`, shared with the driver) from `AxisModel`s. Its
action callback runs before written values are stored: on a write that reaches
a command register it executes the command from the values being written
(merged with the stored parameters) and clears the command bits in them; on a
read it first refreshes the read-only registers from the models, so reads see
a move in progress on the simulated clock.

Faults are injected on demand, per request, optionally only for requests to
one axis block. They use the server's hooks: `trace_pdu` (a request returned
as None is never executed nor answered), the action (exception reply), and
`trace_packet` (corrupt the reply bytes: one flipped bit on RTU, caught by the
CRC; a short frame on Modbus/TCP, which has no checksum of its own).
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Self, cast

from pymodbus import FramerType
from pymodbus.constants import ExcCodes
from pymodbus.pdu import ModbusPDU
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.server.base import ModbusBaseServer
from pymodbus.simulator import DataType, SimData, SimDevice

from rig.config.rigfile import AxisConfig
from rig.drivers.modbus_axis_map import (
    BLOCK_REGS,
    FIRMWARE,
    MODEL,
    MOVE_REGS,
    TEXT_REGS,
    VENDOR,
    Command,
    Reg,
    Status,
    axis_base,
    int32_to_regs,
    register_axis,
    regs_to_int32,
    text_to_regs,
)
from rig.simulators.axis_model import AxisModel
from rig.simulators.faults import AXIS_FAULTS
from rig.simulators.world import SimWorld

IDENTITY = {VENDOR: "rig simulators", MODEL: "SIM-2AX Modbus", FIRMWARE: "1.0.0"}


@dataclass
class _Fault:
    kind: str
    count: int
    axis: int | None          # only requests to this axis block; None: any request


def _request_axis(pdu: ModbusPDU) -> int:
    """Axis block a request addresses (-1: the identity block)."""
    address: int = getattr(pdu, "write_address") if pdu.function_code == 23 else pdu.address  # noqa: B009
    return register_axis(address)


class ModbusAxisServer:
    def __init__(self, world: SimWorld, axes: list[tuple[str, AxisConfig]], *, steps_per_degree: float = 1000.0,
                 device_id: int = 1, framer: str = "tcp"):
        if framer not in ("tcp", "rtu"):
            raise ValueError(f"framer {framer!r}: use 'tcp' or 'rtu'")
        self.world = world
        self.steps_per_degree = steps_per_degree
        self.device_id = device_id
        self.framer = framer
        self.models = [AxisModel(world, name, cfg, steps_per_degree=steps_per_degree) for name, cfg in axes]
        self.url: str | None = None
        self._faults: list[_Fault] = []
        self._lock = threading.Lock()
        self._armed: str | None = None        # fault chosen for the request in progress
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._server: ModbusBaseServer | None = None

    # -- life cycle ---------------------------------------------------------------------------
    def start(self) -> str:
        """Serve on a free loopback port; returns the driver URL."""
        if self._thread is not None and self.url is not None:
            return self.url
        loop = self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=loop.run_forever, name=f"ModbusAxisServer-{id(self):x}",
                                        daemon=True)
        self._thread.start()
        try:
            port = asyncio.run_coroutine_threadsafe(self._serve(), loop).result(timeout=5.0)
        except BaseException:
            self.stop()
            raise
        scheme = "modbus-tcp://" if self.framer == "tcp" else "modbus-rtu://socket://"
        url = self.url = f"{scheme}127.0.0.1:{port}"
        return url

    def stop(self) -> None:
        """Close the server and its connections, end the loop and join the thread (idempotent)."""
        loop, thread = self._loop, self._thread
        if loop is None or thread is None:
            return
        if self._server is not None:
            asyncio.run_coroutine_threadsafe(self._shutdown(self._server), loop).result(timeout=5.0)
        loop.call_soon_threadsafe(loop.stop)
        thread.join(timeout=5.0)
        loop.close()
        self._thread = self._loop = self._server = None

    def __enter__(self) -> Self:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    async def _serve(self) -> int:
        device = SimDevice(self.device_id, simdata=self._simdata(), action=self._on_request)
        # pymodbus drops a request whose trace_pdu hook returns None, though its annotation says ModbusPDU
        on_pdu = cast(Callable[[bool, ModbusPDU], ModbusPDU], self._on_pdu)
        server: ModbusBaseServer
        if self.framer == "tcp":
            server = ModbusTcpServer(device, address=("127.0.0.1", 0), trace_pdu=on_pdu, trace_packet=self._on_packet)
        else:   # pymodbus listens on TCP for a socket:// "serial port" and frames RTU on it
            server = ModbusSerialServer(device, port="socket://127.0.0.1:0", framer=FramerType.RTU,
                                        trace_pdu=on_pdu, trace_packet=self._on_packet)
        await server.serve_forever(background=True)
        self._server = server
        listener = cast(asyncio.Server, server.transport)      # a listening server's transport
        return int(listener.sockets[0].getsockname()[1])

    @staticmethod
    async def _shutdown(server: ModbusBaseServer) -> None:
        await server.shutdown()
        if ModbusBaseServer.active_server is server:    # pymodbus keeps the last server in a class attribute
            ModbusBaseServer.active_server = None
        tasks = [t for t in asyncio.all_tasks() if t is not asyncio.current_task()]
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)

    # -- faults -------------------------------------------------------------------------------
    def inject(self, fault: str, count: int = 1, axis: int | None = None) -> None:
        """Make the next `count` requests (to axis block `axis`, or any) fail; "alarm": the next
        `count` moves of `axis` (default 0) end in alarm 0x10 (excessive position deviation)."""
        AXIS_FAULTS.check(fault, count)
        if fault == "alarm":
            self.models[axis or 0].inject_alarm(moves=count)
            return
        with self._lock:
            self._faults.append(_Fault(fault, count, axis))

    def _take_fault(self, axis: int) -> str | None:
        with self._lock:
            for fault in self._faults:
                if fault.axis is None or fault.axis == axis:
                    fault.count -= 1
                    if fault.count == 0:
                        self._faults.remove(fault)
                    return fault.kind
        return None

    def _on_pdu(self, sending: bool, pdu: ModbusPDU) -> ModbusPDU | None:
        if sending:
            return pdu
        fault = self._take_fault(_request_axis(pdu))
        if fault == "disconnect" and self._server is not None:
            for connection in list(self._server.active_connections.values()):
                connection.close()
        if fault in ("no_reply", "disconnect"):
            return None                     # never executed, never answered
        self._armed = fault                 # "exception": _on_request; "garbled": _on_packet
        return pdu

    def _on_packet(self, sending: bool, data: bytes) -> bytes:
        if not (sending and self._armed == "garbled"):
            return data
        self._armed = None
        if self.framer == "tcp":            # Modbus/TCP has no checksum: garble = a short frame
            return data[:-1]
        middle = len(data) // 2             # RTU: one flipped bit, caught by the CRC
        return data[:middle] + bytes([data[middle] ^ 0x10]) + data[middle + 1:]

    # -- register map -------------------------------------------------------------------------
    def _simdata(self) -> list[SimData]:
        identity = [reg for address, text in IDENTITY.items() for reg in text_to_regs(text, TEXT_REGS[address])]
        data = [SimData(VENDOR, values=identity + int32_to_regs(len(self.models)), datatype=DataType.REGISTERS,
                        readonly=True)]
        for index, model in enumerate(self.models):
            base = axis_base(index)
            parameters = int32_to_regs(0, round(model.cfg.speed_deg_s * self.steps_per_degree),
                                       round(model.cfg.accel_deg_s2 * self.steps_per_degree), 0)
            data.append(SimData(base, values=parameters, datatype=DataType.REGISTERS))
            data.append(SimData(base + Reg.STATUS, values=self._feedback(model), datatype=DataType.REGISTERS,
                                readonly=True))
        return data

    def _feedback(self, model: AxisModel) -> list[int]:
        """Registers STATUS … LIMIT_HIGH as they read now."""
        s = model.state()
        status = ((Status.READY if not (s.busy or s.alarm) else 0) | (Status.BUSY if s.busy else 0)
                  | (Status.IN_POSITION if s.in_position else 0) | (Status.ALARM if s.alarm else 0)
                  | (Status.HOMED if s.homed else 0))
        lo, hi = (round(limit * self.steps_per_degree) for limit in model.cfg.limits_deg)
        return int32_to_regs(status, s.alarm, s.encoder_steps, s.command_steps, lo, hi)

    async def _on_request(self, function_code: int, start: int, address: int, count: int, registers: list[int],
                          values: list[int] | list[bool] | None) -> ExcCodes | None:
        if self._armed == "exception":
            self._armed = None
            return ExcCodes.DEVICE_FAILURE
        if values is None:
            for index, model in enumerate(self.models):
                first = axis_base(index) + Reg.STATUS - start
                registers[first:first + BLOCK_REGS - Reg.STATUS] = self._feedback(model)
            return None
        for index, model in enumerate(self.models):
            base = axis_base(index)
            if address <= base + Reg.COMMAND + 1 < address + count:     # the command word was written
                return self._execute(model, registers[base - start:base - start + MOVE_REGS],
                                     cast(list[int], values), address - base)    # holding registers: ints
        return None

    def _execute(self, model: AxisModel, stored: list[int], values: list[int], offset: int) -> ExcCodes | None:
        """Run the command being written, with parameters merged from `values` over `stored`; clear it."""
        block = stored[:offset] + values + stored[offset + len(values):]
        target, speed, accel, command = regs_to_int32(block[:MOVE_REGS])
        command = Command(command)
        if Command.START in command and (speed <= 0 or accel <= 0):
            return ExcCodes.ILLEGAL_VALUE
        for i in range(max(Reg.COMMAND - offset, 0), Reg.COMMAND + 2 - offset):
            values[i] = 0                   # command bits clear themselves
        spd = self.steps_per_degree
        if Command.ALARM_RESET in command:
            model.reset_alarm()
        if Command.STOP in command:
            model.stop()
        if Command.HOME in command:
            model.home()
        if Command.START in command:
            model.start_move(target / spd, speed / spd, accel / spd)
        return None
