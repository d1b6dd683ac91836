"""Two-axis motion controller over Modbus TCP or RTU, as `Axis` objects.

The register map (docs/modbus-axis-register-map.md, as data in
`rig.drivers.modbus_axis_map`) follows industrial drives such as the Oriental
Motor AZ series; the simulated controller serves the same one.

One request per action: a move writes target, speed, acceleration and the
START command in one read/write transaction (FC 23) whose read half returns
the state the move starts from, so `wait` can sleep the predicted move time and
then confirm it with a single status read. No reply, a dropped link or a
garbled frame is transient (retried after a reconnect, reported as an event);
a Modbus exception reply or an alarm is not. The client comes from
`open_client` (`modbus_client` by default), so a test can replay a scripted
exchange of exact PDUs in memory.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, ClassVar
from urllib.parse import parse_qs

from pymodbus import FramerType
from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.constants import ExcCodes
from pymodbus.exceptions import ModbusException
from pymodbus.pdu import ModbusPDU

from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.core.motion import move_time_s
from rig.drivers.interfaces import Axis, TwoAxisPositioner
from rig.drivers.modbus_axis_map import (
    ALARMS,
    IDENTITY_REGS,
    STATE_REGS,
    TEXT_REGS,
    VENDOR,
    Command,
    Reg,
    Status,
    axis_base,
    int32_to_regs,
    regs_to_int32,
    regs_to_text,
)
from rig.drivers.retry import DEFAULT_RETRY, RetryingDevice, RetryPolicy

# Every failed exchange becomes a DeviceError or a retry event of ours, naming the axis
# and register; pymodbus' own ERROR lines (with hex dumps) would only repeat them.
logging.getLogger("pymodbus").setLevel(logging.CRITICAL)

# -- transport ----------------------------------------------------------------------------------
_SERIAL_OPTIONS = ("baudrate", "parity", "stopbits", "bytesize")
ModbusClient = ModbusTcpClient | ModbusSerialClient
#: `modbus_client`'s signature: how a controller gets its client.
ClientOpener = Callable[[str, float], ModbusClient]


def modbus_client(url: str, timeout_s: float) -> ModbusClient:
    """`modbus-tcp://host:port` or `modbus-rtu://<device path or pyserial URL>?baudrate=N`.

    pymodbus' own retries are off: retries, reconnects and their events are ours.
    """
    scheme, _, rest = url.partition("://")
    if scheme == "modbus-tcp":
        host, _, port = rest.rpartition(":")
        if not host or not port.isdigit():
            raise ValueError(f"{url!r}: expected modbus-tcp://host:port")
        return ModbusTcpClient(host, port=int(port), timeout=timeout_s, retries=0)
    if scheme == "modbus-rtu":
        port, _, query = rest.partition("?")
        options = {key: values[-1] for key, values in parse_qs(query).items()}
        for key in options:
            if key not in _SERIAL_OPTIONS:
                raise ValueError(f"{url!r}: unknown option {key!r} (known: {', '.join(_SERIAL_OPTIONS)})")
        # pymodbus' defaults, except the baud rate: 115200 is the AZ drives' factory setting
        return ModbusSerialClient(port, framer=FramerType.RTU, timeout=timeout_s, retries=0,
                                  baudrate=int(options.get("baudrate", 115200)), parity=options.get("parity", "N"),
                                  stopbits=int(options.get("stopbits", 1)), bytesize=int(options.get("bytesize", 8)))
    raise ValueError(f"{url!r}: expected modbus-tcp://host:port or modbus-rtu://<port>?baudrate=N")


def _exception_name(code: int) -> str:
    try:
        return ExcCodes(code).name.lower().replace("_", " ")
    except ValueError:
        return "unknown exception"


class ModbusAxisController(RetryingDevice):
    """One Modbus device (controller) with up to a few axes; owns the connection."""

    ROLE: ClassVar[str] = "positioner"          # its role among installed drivers (rig.drivers.registry)

    @classmethod
    def from_rig(cls, *, clock: Clock, settings: Mapping[str, Any], name: str, address: str, device_id: int = 1,
                 steps_per_degree: float = 1000.0, timeout_s: float = 1.0) -> TwoAxisPositioner:
        """The rig-file contract (rig.drivers.registry) for a positioner: `settings` maps the positioner's two
        axis names, in controller axis order, to their rig-file sections (speed, acceleration, settling).
        Connects at once: a wrong address fails here, not at the first move."""
        controller = cls(address, device_id=device_id, name=name, clock=clock, timeout_s=timeout_s)
        try:
            controller.identity()
        except BaseException:
            controller.close()
            raise
        axes = [controller.axis(index, axis_name, steps_per_degree, cfg.speed_deg_s, cfg.accel_deg_s2, cfg.settle_s)
                for index, (axis_name, cfg) in enumerate(settings.items())]
        return TwoAxisPositioner(name, axes[0], axes[1])

    def __init__(self, url: str, *, device_id: int = 1, name: str, clock: Clock, timeout_s: float = 1.0,
                 retry: RetryPolicy = DEFAULT_RETRY, open_client: ClientOpener = modbus_client):
        super().__init__(name, clock, retry)
        self.url = url
        self.device_id = device_id
        self._client = open_client(url, timeout_s)
        self._identity: str | None = None

    def axis(self, index: int, name: str, steps_per_degree: float, speed_deg_s: float, accel_deg_s2: float,
             settle_s: float) -> ModbusAxis:
        return ModbusAxis(self, index, name, steps_per_degree, speed_deg_s, accel_deg_s2, settle_s)

    def identity(self) -> str:
        """Vendor, model and firmware from the identity registers (read once: they do not change)."""
        if self._identity is None:
            regs = self.read(self.name, "read identity", VENDOR, IDENTITY_REGS)
            vendor, model, firmware = (regs_to_text(regs[a:a + n]) for a, n in TEXT_REGS.items())
            self._identity = f"{vendor} {model} fw {firmware} (id {self.device_id} at {self.url})"
        return self._identity

    def close(self) -> None:
        self._client.close()

    # -- exchanges: each one request, under the retry policy ----------------------------------
    def read(self, device: str, what: str, address: int, count: int) -> list[int]:
        reply = self._exchange(device, what, address, count, lambda c: c.read_holding_registers(
            address, count=count, device_id=self.device_id))
        return list(reply.registers)

    def write(self, device: str, what: str, address: int, values: list[int]) -> None:
        self._exchange(device, what, address, 0, lambda c: c.write_registers(
            address, values, device_id=self.device_id))

    def write_read(self, device: str, what: str, write_address: int, values: list[int], read_address: int,
                   count: int) -> list[int]:
        """Write, then read, in one transaction (FC 23; the device writes first)."""
        reply = self._exchange(device, what, write_address, count, lambda c: c.readwrite_registers(
            write_address=write_address, values=values, read_address=read_address, read_count=count,
            device_id=self.device_id))
        return list(reply.registers)

    def _exchange(self, device: str, what: str, address: int, count: int,
                  request: Callable[[ModbusClient], ModbusPDU]) -> ModbusPDU:
        where = f"controller {self.name!r}: {what} at register 0x{address:04X} (id {self.device_id}, {self.url})"

        def once() -> ModbusPDU:
            try:
                reply = request(self._client)
            except (ModbusException, OSError) as exc:
                raise DeviceError(device, f"{where}: no valid reply: {exc}", transient=True) from None
            if reply.isError():
                raise DeviceError(device, f"{where} answered Modbus exception {reply.exception_code} "
                                          f"({_exception_name(reply.exception_code)})")
            if count and len(reply.registers) != count:
                raise DeviceError(device, f"{where}: {len(reply.registers)} registers in the reply, "
                                          f"expected {count}", transient=True)
            return reply

        return self.retrying(what, once, device=device)

    def reconnect(self) -> None:
        self._client.close()
        if not self._client.connect():
            raise DeviceError(self.name, f"cannot connect to {self.url}", transient=True)


@dataclass(frozen=True)
class AxisState:
    status: Status
    alarm: int
    encoder_steps: int
    command_steps: int


class ModbusAxis(Axis):
    #: Rig time between status polls once the predicted move time has passed.
    poll_s = 0.02
    #: Added to the predicted move time so float rounding of clock sums never costs a poll.
    _GUARD_S = 1e-6

    def __init__(self, controller: ModbusAxisController, index: int, name: str, steps_per_degree: float,
                 speed_deg_s: float, accel_deg_s2: float, settle_s: float):
        self.controller = controller
        self.index = index
        self.name = name
        self.base = axis_base(index)
        self.steps_per_degree = steps_per_degree
        self.speed_steps = round(speed_deg_s * steps_per_degree)
        self.accel_steps = round(accel_deg_s2 * steps_per_degree)
        self.settle_s = settle_s
        self._done_at = 0.0           # rig time at which the last commanded move should be settled

    # -- Axis ---------------------------------------------------------------------------------
    def start_move(self, target_deg: float) -> None:
        target = round(target_deg * self.steps_per_degree)
        values = int32_to_regs(target, self.speed_steps, self.accel_steps, Command.START)
        state = self._command("start move", Reg.TARGET, values)
        start_deg = state.command_steps / self.steps_per_degree
        self._done_at = self.controller.clock.now() + self.move_time_s(start_deg, target / self.steps_per_degree)

    def wait(self, timeout_s: float | None = None) -> None:
        """Sleep the predicted move time, then poll; without a timeout allow twice the prediction + 1 s."""
        clock = self.controller.clock
        remaining = max(self._done_at - clock.now(), 0.0)
        self._settle("move", remaining, 2.0 * remaining + 1.0 if timeout_s is None else timeout_s)

    def position_deg(self) -> float:
        regs = self.controller.read(self.name, "read encoder position", self.base + Reg.ENCODER, 2)
        return regs_to_int32(regs)[0] / self.steps_per_degree

    def is_moving(self) -> bool:
        return Status.BUSY in self.state().status

    def stop(self) -> None:
        self.controller.write(self.name, "stop", self.base + Reg.COMMAND, int32_to_regs(Command.STOP))
        self._done_at = self.controller.clock.now()

    def home(self, timeout_s: float = 60.0) -> None:
        """Run to the home sensor; the sensor search after the run is polled, its length being the drive's."""
        state = self._command("home", Reg.COMMAND, int32_to_regs(Command.HOME))
        run_s = self.move_time_s(state.command_steps / self.steps_per_degree, 0.0)
        state = self._settle("home", run_s, timeout_s)
        if Status.HOMED not in state.status:
            raise DeviceError(self.name, f"homing ended without the homed flag (status {state.status!r})")

    def move_time_s(self, start_deg: float, target_deg: float) -> float:
        return (move_time_s(target_deg - start_deg, self.speed_steps / self.steps_per_degree,
                            self.accel_steps / self.steps_per_degree) + self.settle_s)

    def identity(self) -> str:
        return f"{self.controller.identity()} axis {self.index}"

    def close(self) -> None:
        self.controller.close()

    # -- further commands ---------------------------------------------------------------------
    def reset_alarm(self) -> None:
        self.controller.write(self.name, "alarm reset", self.base + Reg.COMMAND, int32_to_regs(Command.ALARM_RESET))

    def state(self) -> AxisState:
        return self._decode(self.controller.read(self.name, "read status", self.base + Reg.STATUS, STATE_REGS))

    # -- helpers ------------------------------------------------------------------------------
    def _command(self, what: str, offset: Reg, values: list[int]) -> AxisState:
        """Write a command (with its parameters) and read the state it leaves, in one request."""
        state = self._decode(self.controller.write_read(self.name, what, self.base + offset, values,
                                                        self.base + Reg.STATUS, STATE_REGS))
        self._raise_on_alarm(state, what)
        return state

    def _settle(self, what: str, predicted_s: float, timeout_s: float) -> AxisState:
        """Sleep the predicted time (capped by the timeout), then poll until in position."""
        clock = self.controller.clock
        deadline = clock.now() + timeout_s
        clock.sleep(min(predicted_s + self._GUARD_S, timeout_s))
        while True:
            state = self.state()
            self._raise_on_alarm(state, what)
            if Status.IN_POSITION in state.status:
                return state
            left = deadline - clock.now()
            if left <= 0:
                raise DeviceError(self.name, f"{what} not finished after {timeout_s:.3g} s "
                                             f"(status {state.status!r})")
            clock.sleep(min(self.poll_s, left))

    def _raise_on_alarm(self, state: AxisState, what: str) -> None:
        if Status.ALARM in state.status:
            raise DeviceError(self.name, f"{what}: alarm 0x{state.alarm:02X} "
                                         f"({ALARMS.get(state.alarm, 'unknown alarm')}); status register "
                                         f"0x{self.base + Reg.STATUS:04X} = {state.status!r}")

    @staticmethod
    def _decode(regs: list[int]) -> AxisState:
        status, alarm, encoder, command = regs_to_int32(regs)
        return AxisState(Status(status), alarm, encoder, command)
