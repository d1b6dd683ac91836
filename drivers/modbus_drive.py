"""Stepper and servo drives on one Modbus link (RTU on RS-485, or TCP through a gateway), as `Axis` objects.

One drive per axis, addressed by its device id on the shared link; what each
register means comes from the drive model's map (`rig.drivers.modbus_drive_map`,
docs/modbus-drives.md), by default the Oriental Motor AZ series' direct data
operation. A move is one FC 16 write of the map's move block (which starts it);
`wait` sleeps the predicted move time and confirms it with one FC 3 status read;
the position read-back is another FC 3. No function code 23: many drives lack it.

No reply, a dropped link, a garbled frame, or a gateway's exception 0Ah/0Bh
(path unavailable, target did not respond: the gateway's word for the same
silence on its RS-485 side) is transient (retried after a reconnect, reported
as an event); any other exception reply or a drive alarm is not. The client
comes from `open_client` (`modbus_client` by default), so a test can replay a
scripted exchange of exact PDUs in memory.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar
from urllib.parse import parse_qs

from pymodbus import FramerType
from pymodbus.client import ModbusSerialClient, ModbusTcpClient
from pymodbus.exceptions import ModbusException
from pymodbus.pdu import ModbusPDU

from rig.core.clock import Clock
from rig.core.errors import DeviceError
from rig.core.motion import move_time_s
from rig.drivers.interfaces import Axis, TwoAxisPositioner
from rig.drivers.modbus_drive_map import DriveMap, OneShot, load_drive_map
from rig.drivers.retry import DEFAULT_RETRY, RetryingDevice, RetryPolicy

# Every failed exchange becomes a DeviceError or a retry event of ours, naming the axis
# and register; pymodbus' own ERROR lines (with hex dumps) would only repeat them.
logging.getLogger("pymodbus").setLevel(logging.CRITICAL)

# -- transport ----------------------------------------------------------------------------------
_SERIAL_OPTIONS = ("baudrate", "parity", "stopbits", "bytesize")
ModbusClient = ModbusTcpClient | ModbusSerialClient
#: `modbus_client`'s signature: how a link gets its client.
ClientOpener = Callable[[str, float], ModbusClient]


def modbus_client(url: str, timeout_s: float) -> ModbusClient:
    """`modbus-tcp://host:port` or `modbus-rtu://<device path or pyserial URL>?baudrate=N&parity=E`.

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
        # 115200 baud, 8 bits, even parity, 1 stop bit: the AZ drives' factory setting
        return ModbusSerialClient(port, framer=FramerType.RTU, timeout=timeout_s, retries=0,
                                  baudrate=int(options.get("baudrate", 115200)), parity=options.get("parity", "E"),
                                  stopbits=int(options.get("stopbits", 1)), bytesize=int(options.get("bytesize", 8)))
    raise ValueError(f"{url!r}: expected modbus-tcp://host:port or modbus-rtu://<port>?baudrate=N")


#: Exception codes of the Modbus application protocol (V1.1b3, 7), as our messages name them.
EXCEPTIONS = {1: "illegal function", 2: "illegal data address", 3: "illegal data value", 4: "server device failure",
              5: "acknowledge", 6: "server device busy", 8: "memory parity error", 0x0A: "gateway path unavailable",
              0x0B: "gateway target device failed to respond"}
#: What a gateway answers when nothing answered it on the bus: retried like a timeout.
GATEWAY_SILENCE = (0x0A, 0x0B)


class ModbusDriveLink(RetryingDevice):
    """One Modbus link (a serial bus or a TCP gateway) and the drives on it; owns the connection."""

    ROLE: ClassVar[str] = "positioner"          # its role among installed drivers (rig.drivers.registry)

    @classmethod
    def from_rig(cls, *, clock: Clock, settings: Mapping[str, Any], name: str, address: str,
                 map: str = "oriental-az", device_ids: Sequence[int] = (1, 2),
                 steps_per_degree: float | Sequence[float] = 1000.0, timeout_s: float = 1.0) -> TwoAxisPositioner:
        """The rig-file contract (rig.drivers.registry) for a positioner: `settings` maps the positioner's two
        axis names, in order, to their rig-file sections (speed, acceleration, settling); `device_ids` and
        `steps_per_degree` (one for both, or one each) follow the same order. Reads each drive's state at
        once: a wrong address or id fails here, not at the first move."""
        drive_map = load_drive_map(map)
        per_axis = ([float(steps_per_degree)] * 2 if isinstance(steps_per_degree, int | float)
                    else [float(s) for s in steps_per_degree])
        link = cls(address, drive_map, name=name, clock=clock, timeout_s=timeout_s)
        try:
            axes = [link.axis(device_id, axis_name, steps, cfg.speed_deg_s, cfg.accel_deg_s2, cfg.settle_s)
                    for device_id, steps, (axis_name, cfg) in zip(device_ids, per_axis, settings.items(), strict=True)]
            for axis in axes:
                axis.state()
        except BaseException:
            link.close()
            raise
        return TwoAxisPositioner(name, axes[0], axes[1])

    def __init__(self, url: str, drive_map: DriveMap, *, name: str, clock: Clock, timeout_s: float = 1.0,
                 retry: RetryPolicy = DEFAULT_RETRY, open_client: ClientOpener = modbus_client):
        super().__init__(name, clock, retry)
        self.url = url
        self.map = drive_map
        self._client = open_client(url, timeout_s)

    def axis(self, device_id: int, name: str, steps_per_degree: float, speed_deg_s: float, accel_deg_s2: float,
             settle_s: float) -> ModbusDriveAxis:
        return ModbusDriveAxis(self, device_id, name, steps_per_degree, speed_deg_s, accel_deg_s2, settle_s)

    def close(self) -> None:
        self._client.close()

    # -- exchanges: each one request, under the retry policy ----------------------------------
    def read(self, device_id: int, device: str, what: str, address: int, count: int) -> list[int]:
        """FC 3: `count` holding registers from `address`."""
        reply = self._exchange(device_id, device, what, address, count, lambda c: c.read_holding_registers(
            address, count=count, device_id=device_id))
        return list(reply.registers)

    def write(self, device_id: int, device: str, what: str, address: int, values: list[int]) -> None:
        """FC 16: `values` (registers) from `address`."""
        self._exchange(device_id, device, what, address, 0, lambda c: c.write_registers(
            address, values, device_id=device_id))

    def _exchange(self, device_id: int, device: str, what: str, address: int, count: int,
                  request: Callable[[ModbusClient], ModbusPDU]) -> ModbusPDU:
        where = f"{self.map.drive} drive (Modbus id {device_id} at {self.url}): {what} at register 0x{address:04X}"

        def once() -> ModbusPDU:
            try:
                reply = request(self._client)
            except (ModbusException, OSError) as exc:
                raise DeviceError(device, f"{where}: no valid reply: {exc}", transient=True) from None
            if reply.isError():
                code = reply.exception_code
                raise DeviceError(device, f"{where} answered Modbus exception 0x{code:02X} "
                                          f"({EXCEPTIONS.get(code, 'not a standard exception code')})",
                                  transient=code in GATEWAY_SILENCE)
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
class DriveState:
    """The map's status bits and, when the alarm bit is set, the present alarm code (else 0)."""

    ready: bool
    alarm: bool
    moving: bool
    in_position: bool
    alarm_code: int
    status_word: int


class ModbusDriveAxis(Axis):
    #: Rig time between state polls once the predicted move time has passed.
    poll_s = 0.02
    #: Added to the predicted move time so float rounding of clock sums never costs a poll.
    _GUARD_S = 1e-6

    def __init__(self, link: ModbusDriveLink, device_id: int, name: str, steps_per_degree: float,
                 speed_deg_s: float, accel_deg_s2: float, settle_s: float):
        self.controller = link            # the shared link: its retries and events are the axis's
        self.map = link.map
        self.device_id = device_id
        self.name = name
        self.steps_per_degree = steps_per_degree
        self.speed_steps = round(speed_deg_s * steps_per_degree)
        self.accel_steps = round(accel_deg_s2 * steps_per_degree)
        self.settle_s = settle_s
        self._done_at = 0.0           # rig time at which the last commanded move should be settled
        self._at_steps: int | None = None     # where the drive is (or is going); None: unknown, read it

    # -- Axis ---------------------------------------------------------------------------------
    def start_move(self, target_deg: float) -> None:
        target = round(target_deg * self.steps_per_degree)
        start = self._where_steps()
        counts = {"target": target, "speed": round(self.speed_steps * self.map.speed_per_step_s),
                  "accel": round(self.accel_steps * self.map.accel_per_step_s2)}
        counts["decel"] = counts["accel"]
        values = [counts[v] if isinstance(v, str) else v for v in self.map.move.values]
        self._write("start move", self.map.move.address, values)
        self._at_steps = target
        # From the steps sent, not the degrees asked: a prediction short of the drive's own move by the rounding
        # (up to half a step) would cost a second status poll and a poll interval of rig time.
        self._done_at = self.controller.clock.now() + self.move_time_s(start / self.steps_per_degree,
                                                                       target / self.steps_per_degree)

    def wait(self, timeout_s: float | None = None) -> None:
        """Sleep the predicted move time, then poll; without a timeout allow twice the prediction + 1 s."""
        remaining = max(self._done_at - self.controller.clock.now(), 0.0)
        self._settle("move", remaining, 2.0 * remaining + 1.0 if timeout_s is None else timeout_s)

    def position_deg(self) -> float:
        steps = self._read_int32("read feedback position", self.map.position.address)
        if self._at_steps is None:           # where the next move starts from, unless one is under way
            self._at_steps = steps
        return steps / self.steps_per_degree

    def is_moving(self) -> bool:
        return self.state().moving

    def stop(self) -> None:
        self._one_shot("stop", self.map.commands.stop)
        self._at_steps = None
        self._done_at = self.controller.clock.now()

    def home(self, timeout_s: float = 60.0) -> None:
        """Return to the drive's home position (position 0) and wait until it is there."""
        start = self._where_steps()
        self._one_shot("return to home", self.map.commands.home)
        self._at_steps = 0
        self._settle("return to home", self.move_time_s(start / self.steps_per_degree, 0.0), timeout_s)

    def move_time_s(self, start_deg: float, target_deg: float) -> float:
        return (move_time_s(target_deg - start_deg, self.speed_steps / self.steps_per_degree,
                            self.accel_steps / self.steps_per_degree) + self.settle_s)

    def identity(self) -> str:
        return f"{self.map.drive} drive, Modbus id {self.device_id} at {self.controller.url}"

    def close(self) -> None:
        self.controller.close()

    # -- further commands ---------------------------------------------------------------------
    def reset_alarm(self) -> None:
        self._one_shot("alarm reset", self.map.commands.alarm_reset)

    def state(self) -> DriveState:
        """The status bits; the alarm code is read only when the alarm bit is set."""
        status = self._read_int32("read status", self.map.status.address) & 0xFFFFFFFF
        bits = self.map.status.bits
        alarm = bool(status >> bits.alarm & 1)
        code = self._read_int32("read alarm code", self.map.alarm_code.address) if alarm else 0
        return DriveState(ready=bool(status >> bits.ready & 1), alarm=alarm, moving=bool(status >> bits.moving & 1),
                          in_position=bool(status >> bits.in_position & 1), alarm_code=code, status_word=status)

    # -- helpers ------------------------------------------------------------------------------
    def _where_steps(self) -> int:
        if self._at_steps is None:
            self._at_steps = self._read_int32("read feedback position", self.map.position.address)
        return self._at_steps

    def _read_int32(self, what: str, address: int) -> int:
        return self.map.from_registers(self.controller.read(self.device_id, self.name, what, address, 2))[0]

    def _write(self, what: str, address: int, values: list[int]) -> None:
        self.controller.write(self.device_id, self.name, what, address, self.map.to_registers(values))

    def _one_shot(self, what: str, command: OneShot) -> None:
        self._write(what, command.address, [command.value])

    def _settle(self, what: str, predicted_s: float, timeout_s: float) -> DriveState:
        """Sleep the predicted time (capped by the timeout), then poll until in position and at rest."""
        clock = self.controller.clock
        deadline = clock.now() + timeout_s
        clock.sleep(min(predicted_s + self._GUARD_S, timeout_s))
        while True:
            state = self.state()
            if state.alarm:
                self._at_steps = None
                raise DeviceError(self.name, f"{what}: alarm 0x{state.alarm_code:02X} "
                                             f"({self.map.alarm_text(state.alarm_code)}) on {self.identity()}")
            if state.in_position and not state.moving:
                return state
            left = deadline - clock.now()
            if left <= 0:
                raise DeviceError(self.name, f"{what} not finished after {timeout_s:.3g} s on {self.identity()} "
                                             f"(status word 0x{state.status_word:08X})")
            clock.sleep(min(self.poll_s, left))
