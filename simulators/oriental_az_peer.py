"""Protocol peer of Oriental Motor AZ drives: simulated drives on one Modbus link, on loopback.

Written from the public description of the AZ series' Modbus interface
(docs/modbus-drives.md: Oriental Motor Europe FAQ 0331, the drivers of
pcegli82/VTICH_VJ_OrientalMaster and asukiaaa/arduino-OrientalAZ, and captured
exchanges), not from rig's drive map: the addresses below are this module's own.
One pymodbus 3.16 server (SimDevice per drive id) in a background thread with
its own event loop; each drive moves an `AxisModel` on the simulated clock.

Served per drive, every value an int32 pair, upper word first:
- 0x0058-0x0069 direct data: operation No., type (1 absolute, 2 incremental from the
  command position), position, speed [Hz], acceleration and deceleration rates
  [0.001 kHz/s], current [0.1 %], trigger, forwarding destination. Writing trigger 1
  starts the operation with the data as they stand after the write (forwarding 0:
  at once, replacing a move in progress); the trigger then reads 0. Trigger 0 only
  stores. A speed or rate of 0 or a current beyond 100 % is operation data error
  alarm 70h. Other triggers (partial updates) and forwarding 1 are not modelled:
  exception 03.
- 0x0078-79 driver input with automatic OFF, 0x007C-7D driver input (level): ZHOME
  (bit 4, high-speed return to position 0), STOP (bit 5; while held ON no operation
  starts), ALM-RST (bit 7) act on an OFF→ON edge. START, FREE and FW/RV-POS (operation
  data tables, jogging, de-energising) are not modelled: exception 03.
- 0x007E-7F driver output: READY (bit 5), ALM-A (7), SYS-BSY (8, never set here),
  MOVE (13), IN-POS (14: a positioning operation has ended in position; off at power-on,
  as in the captured status reply, and after STOP). 0x0080-81 present alarm code.
- 0x00CC-CD feedback position [steps], 0x00CE-CF feedback speed [r/min of the motor shaft, at the
  factory resolution of 1000 steps per revolution], 0x00D0-D1 feedback speed [Hz]; signed. This
  model's feedback speed is that of the command profile.
- 0x0180-81 alarm reset: executed when written 1 after 0 (the maintenance command).
- 0x1800-0x57FF operation data No. 0-255, 0x40 registers (32 pairs) each: type, position, speed,
  starting and stopping rates, current, ... from +0x00, +0x02, ... (the maker's FAQ 0331 writes No. 0's
  position at 0x1802; the rest of the layout is from other public descriptions, not the manual).
  Stored as written and read back; running them (START) is not modelled.
Any other address answers exception 02, as does writing a read-only register. Function codes
03, 06, 08 (sub-function 00h, the echo) and 10h are served; any other answers exception 01.

A unit that is not on the link never answers on RTU (an RS-485 bus is silent), nor through a
transparent Modbus/TCP converter; with `gateway=True` (Modbus/TCP through a gateway to the bus)
the gateway answers exception 0Bh (gateway target device failed to respond) for it. Id 0 on RTU
is the broadcast: every drive executes the request and none answers.

Faults are injected on demand, per request, optionally only for one drive: "no_reply" and
"disconnect" (the request is never executed nor answered), "exception" (04, device
failure), "garbled" (one flipped bit on RTU, caught by the CRC; a short frame on
Modbus/TCP, which has no checksum of its own), "alarm" (the next moves end in alarm 10h).
"""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Self, cast

from pymodbus import FramerType
from pymodbus.client.mixin import ModbusClientMixin
from pymodbus.constants import ExcCodes
from pymodbus.datastore import ModbusServerContext
from pymodbus.pdu import ExceptionResponse, ModbusPDU
from pymodbus.server import ModbusSerialServer, ModbusTcpServer
from pymodbus.server.base import ModbusBaseServer
from pymodbus.simulator import DataType, SimData, SimDevice

from rig.config.rigfile import AxisConfig
from rig.simulators.axis_model import Alarm, AxisModel
from rig.simulators.faults import AXIS_FAULTS
from rig.simulators.world import SimWorld

DIRECT_DATA = 0x0058          # 9 pairs: No., type, position, speed, accel, decel, current, trigger, forwarding
TYPE, POSITION, SPEED, ACCEL, DECEL, CURRENT, TRIGGER, FORWARDING = range(1, 9)     # pair index in the block
INPUT_AUTO_OFF, INPUT, OUTPUT, PRESENT_ALARM = 0x0078, 0x007C, 0x007E, 0x0080
FEEDBACK = 0x00CC             # 3 pairs: position [steps], speed [r/min], speed [Hz]
STEPS_PER_MOTOR_REV = 1000    # the AZ's factory resolution: what the r/min of the feedback speed is of
OPERATION_DATA, OPERATION_DATA_STRIDE, OPERATION_DATA_COUNT = 0x1800, 0x40, 256
ALARM_RESET = 0x0180
#: The function codes an AZ drive serves: read holding registers, write one, diagnostics (echo only), write many.
FUNCTIONS = (3, 6, 8, 16)
ZHOME, STOP, ALM_RST = 1 << 4, 1 << 5, 1 << 7
UNMODELLED_INPUTS = 1 << 3 | 1 << 6 | 1 << 14 | 1 << 15        # START, FREE, FW-POS, RV-POS
READY, ALM_A, MOVE, IN_POS = 1 << 5, 1 << 7, 1 << 13, 1 << 14
#: Direct data at power-on: No. 0, absolute, position 0, 1 kHz, 1 kHz/s, 1 kHz/s, 100 %, trigger 0.
DIRECT_DEFAULTS = (0, 1, 0, 1000, 1000, 1000, 1000, 0, 0)
#: Each operation data No. at power-on (the peer's choice): incremental, 0 steps, 1 kHz, 1 kHz/s, 1 kHz/s, 100 %.
OPERATION_DEFAULTS = (2, 0, 1000, 1000, 1000, 1000) + (0,) * (OPERATION_DATA_STRIDE // 2 - 6)


def pairs(*values: int) -> list[int]:
    """int32 values as register pairs, upper word first."""
    return ModbusClientMixin.convert_to_registers(list(values), ModbusClientMixin.DATATYPE.INT32)


def values_of(registers: Sequence[int]) -> list[int]:
    decoded = ModbusClientMixin.convert_from_registers(list(registers), ModbusClientMixin.DATATYPE.INT32)
    return [int(v) for v in (decoded if isinstance(decoded, list) else [decoded])]


def _written(address: int, count: int, register: int) -> bool:
    """Whether a write of `count` registers from `address` reaches the pair at `register`."""
    return address < register + 2 and register < address + count


@dataclass
class _Fault:
    kind: str
    count: int
    device_id: int | None          # only requests to this drive; None: any request


class _Refused(ModbusPDU):
    """A request answered with an exception before any register is looked at: a function the drive lacks (01h),
    or, from a gateway, a unit absent from the bus behind it (0Bh)."""

    def __init__(self, request: ModbusPDU, code: ExcCodes):
        super().__init__(dev_id=request.dev_id, transaction_id=request.transaction_id)
        self.function_code = request.function_code
        self.code = code

    async def datastore_update(self, context: ModbusServerContext, device_id: int) -> ModbusPDU:
        return ExceptionResponse(self.function_code, self.code)


class _Drive:
    """One AZ drive: its AxisModel and the input and alarm-reset levels that edges are taken from."""

    def __init__(self, model: AxisModel, steps_per_degree: float):
        self.model = model
        self.steps_per_degree = steps_per_degree
        self.inputs = 0                # level of 0x007C-7D
        self.reset_level = 0           # last value written to 0x0180-81
        self.positioned = False        # a positioning operation was started since power-on or the last STOP

    def output(self) -> list[int]:
        """0x007E-0x0081: output status and present alarm, as they read now."""
        s = self.model.state()
        stop_held = bool(self.inputs & STOP)
        status = ((READY if not (s.busy or s.alarm or stop_held) else 0) | (ALM_A if s.alarm else 0)
                  | (MOVE if s.busy else 0) | (IN_POS if s.in_position and self.positioned else 0))
        return pairs(status, s.alarm)

    def feedback(self) -> list[int]:
        """0x00CC-0x00D1: feedback position, speed in r/min and in Hz, as they read now."""
        hz = self.model.command_speed_deg_s() * self.steps_per_degree
        return pairs(self.model.state().encoder_steps, round(hz * 60 / STEPS_PER_MOTOR_REV), round(hz))

    def inputs_on(self, rising: int) -> ExcCodes | None:
        if rising & UNMODELLED_INPUTS:
            return ExcCodes.ILLEGAL_VALUE
        if rising & ALM_RST:
            self.model.reset_alarm()
        if rising & STOP:
            self.model.stop()
            self.positioned = False
        if rising & ZHOME and not self.inputs & STOP:
            self.model.home()
            self.positioned = True
        return None

    def direct_operation(self, data: list[int]) -> ExcCodes | None:
        """Start the operation of the direct data `data` (9 values) as written with trigger 1."""
        if data[FORWARDING] != 0 or data[TYPE] not in (1, 2):
            return ExcCodes.ILLEGAL_VALUE
        if self.inputs & STOP:
            return None                                 # not READY: the drive ignores the trigger
        spd = self.steps_per_degree
        if data[SPEED] <= 0 or data[ACCEL] <= 0 or data[DECEL] <= 0 or not 0 <= data[CURRENT] <= 1000:
            self.model.raise_alarm(Alarm.OPERATION_DATA)
            return None
        base_deg = self.model.command_position_deg() if data[TYPE] == 2 else 0.0
        self.model.start_move(base_deg + data[POSITION] / spd, data[SPEED] / spd, data[ACCEL] / spd)
        self.positioned = True
        return None


class OrientalAZPeer:
    """AZ drives, one per (name, axis section), at device ids `device_ids`, on one Modbus/TCP or RTU link."""

    def __init__(self, world: SimWorld, axes: list[tuple[str, AxisConfig]], *, device_ids: Sequence[int] = (1, 2),
                 steps_per_degree: float | Sequence[float] = 1000.0, framer: str = "tcp", gateway: bool = False,
                 backlash_deg: float = 0.002):
        if framer not in ("tcp", "rtu"):
            raise ValueError(f"framer {framer!r}: use 'tcp' or 'rtu'")
        if gateway and framer != "tcp":
            raise ValueError("gateway=True is a Modbus/TCP gateway: use framer 'tcp'")
        steps = ([float(steps_per_degree)] * len(axes) if isinstance(steps_per_degree, int | float)
                 else list(steps_per_degree))
        self.world = world
        self.framer = framer
        self.gateway = gateway
        self.drives = {device_id: _Drive(AxisModel(world, name, cfg, steps_per_degree=s, backlash_deg=backlash_deg,
                                                     home_search_s=0.0), s)
                       for device_id, s, (name, cfg) in zip(device_ids, steps, axes, strict=True)}
        self.url: str | None = None
        self._faults: list[_Fault] = []
        self._lock = threading.Lock()
        self._armed: str | None = None        # fault chosen for the request in progress
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._server: ModbusBaseServer | None = None

    @property
    def models(self) -> list[AxisModel]:
        return [drive.model for drive in self.drives.values()]

    # -- life cycle ---------------------------------------------------------------------------
    def start(self) -> str:
        """Serve on a free loopback port; returns the driver URL."""
        if self._thread is not None and self.url is not None:
            return self.url
        loop = self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=loop.run_forever, name=f"OrientalAZPeer-{id(self):x}", daemon=True)
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
        devices = [SimDevice(device_id, simdata=self._simdata(), action=self._action(drive))
                   for device_id, drive in self.drives.items()]
        # pymodbus drops a request whose trace_pdu hook returns None, though its annotation says ModbusPDU
        on_pdu = cast(Callable[[bool, ModbusPDU], ModbusPDU], self._on_pdu)
        server: ModbusBaseServer
        if self.framer == "tcp":
            server = ModbusTcpServer(devices, address=("127.0.0.1", 0), trace_pdu=on_pdu,
                                     trace_packet=self._on_packet)
        else:   # pymodbus listens on TCP for a socket:// "serial port" and frames RTU on it
            server = ModbusSerialServer(devices, port="socket://127.0.0.1:0", framer=FramerType.RTU,
                                        trace_pdu=on_pdu, trace_packet=self._on_packet, broadcast_enable=True)
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
        """Make the next `count` requests (to the drive of axis index `axis`, or any) fail; "alarm": the next
        `count` moves of that drive (default the first) end in alarm 10h (excessive position deviation)."""
        AXIS_FAULTS.check(fault, count)
        device_id = None if axis is None else list(self.drives)[axis]
        if fault == "alarm":
            self.models[axis or 0].inject_alarm(Alarm.DEVIATION, moves=count)
            return
        with self._lock:
            self._faults.append(_Fault(fault, count, device_id))

    def _take_fault(self, device_id: int) -> str | None:
        with self._lock:
            for fault in self._faults:
                if fault.device_id is None or fault.device_id == device_id:
                    fault.count -= 1
                    if fault.count == 0:
                        self._faults.remove(fault)
                    return fault.kind
        return None

    def _on_pdu(self, sending: bool, pdu: ModbusPDU) -> ModbusPDU | None:
        if sending:
            return pdu
        if pdu.dev_id not in self.drives and not (pdu.dev_id == 0 and self.framer == "rtu"):
            # nobody on the bus answers; a gateway says so
            return _Refused(pdu, ExcCodes.GATEWAY_NO_RESPONSE) if self.gateway else None
        if pdu.function_code not in FUNCTIONS or pdu.function_code == 8 and pdu.sub_function_code != 0:
            return _Refused(pdu, ExcCodes.ILLEGAL_FUNCTION)
        fault = self._take_fault(pdu.dev_id)
        if fault == "disconnect" and self._server is not None:
            for connection in list(self._server.active_connections.values()):
                connection.close()
        if fault in ("no_reply", "disconnect"):
            return None                     # never executed, never answered
        self._armed = fault                 # "exception": the action; "garbled": _on_packet
        return pdu

    def _on_packet(self, sending: bool, data: bytes) -> bytes:
        if not (sending and self._armed == "garbled"):
            return data
        self._armed = None
        if self.framer == "tcp":            # Modbus/TCP has no checksum: garble = a short frame
            return data[:-1]
        middle = len(data) // 2             # RTU: one flipped bit, caught by the CRC
        return data[:middle] + bytes([data[middle] ^ 0x10]) + data[middle + 1:]

    # -- registers ----------------------------------------------------------------------------
    @staticmethod
    def _simdata() -> list[SimData]:
        def block(address: int, registers: list[int], readonly: bool = False) -> SimData:
            return SimData(address, values=registers, datatype=DataType.REGISTERS, readonly=readonly)
        return [block(DIRECT_DATA, pairs(*DIRECT_DEFAULTS)), block(INPUT_AUTO_OFF, pairs(0)), block(INPUT, pairs(0)),
                block(OUTPUT, pairs(0, 0), readonly=True), block(FEEDBACK, pairs(0, 0, 0), readonly=True),
                block(ALARM_RESET, pairs(0)), block(OPERATION_DATA, pairs(*OPERATION_DEFAULTS) * OPERATION_DATA_COUNT)]

    def _action(self, drive: _Drive):
        async def on_request(function_code: int, start: int, address: int, count: int, registers: list[int],
                             values: list[int] | list[bool] | None) -> ExcCodes | None:
            if self._armed == "exception":
                self._armed = None
                return ExcCodes.DEVICE_FAILURE
            if values is None:                          # a read: refresh what the drive reports
                registers[OUTPUT - start:OUTPUT - start + 4] = drive.output()
                registers[FEEDBACK - start:FEEDBACK - start + 6] = drive.feedback()
                return None
            return self._write(drive, start, address, registers, cast(list[int], values))   # holding: ints
        return on_request

    @staticmethod
    def _write(drive: _Drive, start: int, address: int, registers: list[int], values: list[int]) -> ExcCodes | None:
        """Act on a write before it is stored; `values` may be changed (self-clearing registers)."""
        count = len(values)
        after = registers[:]                             # the register file as it stands after the write
        after[address - start:address - start + count] = values

        def pair(register: int) -> int:
            return values_of(after[register - start:register - start + 2])[0]

        def clear(register: int) -> None:                # the pair reads 0 once the drive has taken it
            for r in (register, register + 1):
                if address <= r < address + count:
                    values[r - address] = 0

        if _written(address, count, DIRECT_DATA + 2 * TRIGGER):
            trigger = pair(DIRECT_DATA + 2 * TRIGGER)
            if trigger not in (0, 1):
                return ExcCodes.ILLEGAL_VALUE
            if trigger == 1:
                refused = drive.direct_operation(values_of(after[DIRECT_DATA - start:DIRECT_DATA - start + 18]))
                if refused:
                    return refused
                clear(DIRECT_DATA + 2 * TRIGGER)
        if _written(address, count, INPUT_AUTO_OFF):
            refused = drive.inputs_on(pair(INPUT_AUTO_OFF) & ~drive.inputs)
            if refused:
                return refused
            clear(INPUT_AUTO_OFF)
        if _written(address, count, INPUT):
            level = pair(INPUT)
            refused = drive.inputs_on(level & ~drive.inputs)
            if refused:
                return refused
            drive.inputs = level
        if _written(address, count, ALARM_RESET):
            level = pair(ALARM_RESET)
            if level == 1 and drive.reset_level != 1:
                drive.model.reset_alarm()
            drive.reset_level = level
        return None
