"""A drive model's Modbus register map, as data: which registers move, report and command one axis.

A map is a YAML file (docs/modbus-drives.md): rig ships the published maps in
`drivers/drive_maps/` and names them by file stem (`oriental-az`); a lab's own
drive is a file of the same form, named by its path. The generic driver
(`rig.drivers.modbus_drive`) reads nothing but the map, so a drive that
positions the same way (write a block of int32 pairs that starts a move, read
a status word and, on alarm, its code; read a position, pulse one-shot inputs) needs
no code. Moves need only function codes 3 and 16: many drives lack FC 23.
"""

from __future__ import annotations

from collections.abc import Sequence
from importlib import resources
from pathlib import Path
from typing import Annotated, Literal

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator
from pymodbus.client.mixin import ModbusClientMixin

#: Names a move's values can take; every other entry of `move.values` is a fixed integer.
MOVE_VARIABLES = ("target", "speed", "accel", "decel")
Address = Annotated[int, Field(ge=0, le=0xFFFE)]
Int32 = Annotated[int, Field(ge=-(2 ** 31), le=2 ** 31 - 1)]
Bit = Annotated[int, Field(ge=0, le=31)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class MoveBlock(_Strict):
    """One FC 16 write of consecutive int32 pairs from `address` that starts an absolute move."""

    address: Address
    values: list[Int32 | Literal["target", "speed", "accel", "decel"]] = Field(min_length=1, max_length=60)

    @model_validator(mode="after")
    def _has_target(self):
        for name in ("target", "speed"):
            if self.values.count(name) != 1:
                raise ValueError(f"values must name {name!r} exactly once")
        return self


class StateBits(_Strict):
    """Bit numbers in the status word (0 = least significant bit of the int32 pair)."""

    ready: Bit
    alarm: Bit
    moving: Bit
    in_position: Bit
    busy: Bit | None = None


class Register(_Strict):
    """An int32 pair read with FC 3."""

    address: Address


class StatusWord(Register):
    bits: StateBits


class OneShot(_Strict):
    """Write `value` (an int32 pair) to `address`: a command the drive takes as one pulse."""

    address: Address
    value: Int32


class Commands(_Strict):
    stop: OneShot
    home: OneShot
    alarm_reset: OneShot


class DriveMap(_Strict):
    drive: str = Field(min_length=1, max_length=200)
    word_order: Literal["big", "little"] = "big"
    move: MoveBlock
    speed_per_step_s: float = Field(gt=0)       # register counts per step/s
    accel_per_step_s2: float = Field(gt=0)      # register counts per step/s²
    status: StatusWord
    alarm_code: Register
    position: Register
    commands: Commands
    alarms: dict[int, str] = Field(default_factory=dict)

    def alarm_text(self, code: int) -> str:
        return self.alarms.get(code, "not in the drive map's alarm list")

    # -- registers <-> int32 values, in the map's word order -----------------------------------
    def to_registers(self, values: Sequence[int]) -> list[int]:
        return ModbusClientMixin.convert_to_registers(list(values), ModbusClientMixin.DATATYPE.INT32,
                                                      word_order=self.word_order)

    def from_registers(self, registers: Sequence[int]) -> list[int]:
        values = ModbusClientMixin.convert_from_registers(list(registers), ModbusClientMixin.DATATYPE.INT32,
                                                          word_order=self.word_order)
        return [int(v) for v in (values if isinstance(values, list) else [values])]


class DriveMapError(ValueError):
    """A drive map that cannot be found, read or understood; the message names the file and key."""


def packaged_maps() -> list[str]:
    """The names of the maps rig ships (`drivers/drive_maps/*.yaml`)."""
    folder = resources.files("rig.drivers").joinpath("drive_maps")
    return sorted(entry.name.removesuffix(".yaml") for entry in folder.iterdir() if entry.name.endswith(".yaml"))


def is_map_path(name_or_path: str) -> bool:
    """Whether a `map` names a file (a path) rather than a packaged map."""
    return name_or_path.endswith((".yaml", ".yml")) or "/" in name_or_path or "\\" in name_or_path


def load_drive_map(name_or_path: str) -> DriveMap:
    """A packaged map by name (`oriental-az`) or a map file by path (`…/my-drive.yaml`)."""
    if is_map_path(name_or_path):
        path = Path(name_or_path)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise DriveMapError(f"drive map {path}: cannot read it: {exc}") from None
        source = str(path)
    elif name_or_path in packaged_maps():
        text = resources.files("rig.drivers").joinpath("drive_maps", f"{name_or_path}.yaml").read_text("utf-8")
        source = f"drive map {name_or_path!r}"
    else:
        raise DriveMapError(f"drive map {name_or_path!r}: no such packaged map (known: {', '.join(packaged_maps())}); "
                            "a map of your own is named by its path, e.g. maps/my-drive.yaml")
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise DriveMapError(f"{source}: not valid YAML: {exc}") from None
    try:
        return DriveMap.model_validate(data)
    except ValidationError as err:
        first = err.errors()[0]
        where = ".".join(str(part) for part in first["loc"]) or "(top level)"
        raise DriveMapError(f"{source}: key {where!r}: {first['msg']}"
                            + (f" ({len(err.errors()) - 1} more problems)" if len(err.errors()) > 1 else "")) from None
