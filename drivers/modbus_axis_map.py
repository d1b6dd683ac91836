"""The register map of a rig axis controller (docs/modbus-axis-register-map.md), as data.

One block of int32 register pairs per axis, upper word first, always read or
written as whole pairs in one request; identity text two characters a
register. The driver (`rig.drivers.modbus_axis`) and the simulated controller
(`rig.simulators.modbus_axis_server`) both speak the map from here, so neither
depends on the other.
"""

from __future__ import annotations

from collections.abc import Sequence
from enum import IntEnum, IntFlag

from pymodbus.client.mixin import ModbusClientMixin

VENDOR, MODEL, FIRMWARE, AXIS_COUNT = 0x0000, 0x0008, 0x0010, 0x0014   # identity block
TEXT_REGS = {VENDOR: 8, MODEL: 8, FIRMWARE: 4}                         # ASCII, 2 characters a register
IDENTITY_REGS = AXIS_COUNT + 2


class Reg(IntEnum):
    """Offsets in the block of axis k at `axis_base(k)`; every entry is an int32 pair."""

    TARGET = 0x00        # steps                      read/write
    SPEED = 0x02         # steps/s                    read/write
    ACCEL = 0x04         # steps/s², also deceleration read/write
    COMMAND = 0x06       # Command bits, self-clearing read/write
    STATUS = 0x08        # Status bits                read
    ALARM = 0x0A         # present alarm code, 0=none read
    ENCODER = 0x0C       # feedback position, steps   read
    COMMAND_POS = 0x0E   # command position, steps    read
    LIMIT_LOW = 0x10     # soft limits, steps         read
    LIMIT_HIGH = 0x12


BLOCK_REGS = 0x14
MOVE_REGS = Reg.STATUS - Reg.TARGET           # target, speed, accel, command: one write
STATE_REGS = Reg.LIMIT_LOW - Reg.STATUS       # status, alarm, encoder, command position: one read


class Command(IntFlag):
    START = 0x01         # move to TARGET at SPEED/ACCEL
    STOP = 0x02          # decelerate to a stop
    HOME = 0x04          # return to the home sensor; sets HOMED and command position 0
    ALARM_RESET = 0x08


class Status(IntFlag):
    READY = 0x01         # no alarm, not busy: accepts a command
    BUSY = 0x02          # moving or settling
    IN_POSITION = 0x04   # move finished and settled
    ALARM = 0x08         # code in ALARM; START/HOME ignored until ALARM_RESET
    HOMED = 0x10


class Alarm(IntEnum):
    DEVIATION = 0x10
    OVERLOAD = 0x30
    HOMING_FAILED = 0x62
    OVERTRAVEL = 0x67


ALARMS: dict[int, str] = {
    Alarm.DEVIATION: "excessive position deviation: stall or obstruction",
    Alarm.OVERLOAD: "overload",
    Alarm.HOMING_FAILED: "homing failed",
    Alarm.OVERTRAVEL: "software overtravel: target beyond the soft limits",
}


def axis_base(index: int) -> int:
    return 0x0100 * (index + 1)


def register_axis(address: int) -> int:
    """The axis whose block holds `address` (-1: the identity block)."""
    return address // 0x0100 - 1


def int32_to_regs(*values: int) -> list[int]:
    """Register pairs, upper word first (pymodbus word_order='big')."""
    return ModbusClientMixin.convert_to_registers(list(values), ModbusClientMixin.DATATYPE.INT32)


def regs_to_int32(regs: Sequence[int]) -> list[int]:
    values = ModbusClientMixin.convert_from_registers(list(regs), ModbusClientMixin.DATATYPE.INT32)
    return [int(v) for v in (values if isinstance(values, list) else [values])]


def text_to_regs(text: str, n_regs: int) -> list[int]:
    """ASCII, first character in the high byte, NUL padded to `n_regs` registers."""
    regs = ModbusClientMixin.convert_to_registers(text, ModbusClientMixin.DATATYPE.STRING,
                                                  string_encoding="ascii")
    if len(regs) > n_regs:
        raise ValueError(f"{text!r} does not fit {n_regs} registers")
    return regs + [0] * (n_regs - len(regs))


def regs_to_text(regs: Sequence[int]) -> str:
    return str(ModbusClientMixin.convert_from_registers(list(regs), ModbusClientMixin.DATATYPE.STRING,
                                                        string_encoding="ascii"))
