"""The `devices` section of a rig file: which driver each device has, with its address and options.

Each device names a driver by its registered name (rig.drivers.registry: rig's own drivers and
any a lab has installed). rig's own drivers have typed entries, validated here in their syntax
(addresses above all); a plug-in driver's entry is its name and its options, every key of the
entry but `driver`, which the plug-in checks itself (rig.devices.check_devices, before
connecting: `rig plan` needs no plug-in installed).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Annotated, Any, ClassVar

from pydantic import AfterValidator, Field, StringConstraints, model_validator

from rig.config.files import short
from rig.config.strict import StrictModel
from rig.drivers.modbus_drive_map import DriveMapError, is_map_path, load_drive_map

#: A device timeout (s).
Seconds = Annotated[float, Field(gt=0, le=60)]
#: A registered driver's name (its entry-point name).
_DRIVER_NAME = re.compile(r"[a-z0-9][a-z0-9_.-]{0,63}")


# -- device addresses ------------------------------------------------------------------------
_HOST_PORT = re.compile(r"(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9](?:[A-Za-z0-9.-]*[A-Za-z0-9])?):(\d{1,5})")
#: pyserial URL handlers (serial_for_url) and whether they need host:port.
_SERIAL_URLS = {"socket": True, "rfc2217": True, "loop": False, "spy": False, "alt": False, "hwgrep": False,
                "cp2110": False}
_SERIAL_PATH = re.compile(r"/[^\s?#]+|COM[1-9]\d{0,2}|\\\\\.\\COM[1-9]\d{0,2}")
#: Modbus RTU options (query of the address) and the values each accepts.
_RTU_OPTIONS: dict[str, Callable[[str], bool]] = {
    "baudrate": lambda v: v.isdigit() and 50 <= int(v) <= 4_000_000,
    "parity": lambda v: v in ("N", "E", "O", "M", "S"),
    "stopbits": lambda v: v in ("1", "2"),
    "bytesize": lambda v: v in ("5", "6", "7", "8"),
}


def _host_port_problem(rest: str) -> str | None:
    m = _HOST_PORT.fullmatch(rest)
    if m is None:
        return "expected host:port"
    if not 1 <= int(m.group(1)) <= 65535:
        return f"port {m.group(1)} outside 1–65535"
    return None


def serial_address_problem(address: str) -> str | None:
    """What is wrong with a serial-line address (device path or pyserial URL), or None."""
    scheme, sep, rest = address.partition("://")
    if not sep:
        return None if _SERIAL_PATH.fullmatch(address) else \
            "expected a serial device path (/dev/ttyUSB0, COM3) or a pyserial URL (socket://host:port)"
    if scheme not in _SERIAL_URLS:
        return f"unknown URL scheme {short(scheme)}; known: {', '.join(_SERIAL_URLS)}"
    if _SERIAL_URLS[scheme]:
        return _host_port_problem(rest.partition("?")[0])
    return None


def modbus_address_problem(address: str) -> str | None:
    """What is wrong with `modbus-tcp://host:port` or `modbus-rtu://<serial>?key=value&…`, or None."""
    scheme, _, rest = address.partition("://")
    if scheme == "modbus-tcp":
        problem = _host_port_problem(rest)
        return f"modbus-tcp: {problem}" if problem else None
    if scheme == "modbus-rtu":
        port, _, query = rest.partition("?")
        problem = serial_address_problem(port)
        if problem:
            return f"modbus-rtu: {problem}"
        for item in filter(None, query.split("&")):
            key, _, value = item.partition("=")
            if key not in _RTU_OPTIONS:
                return f"modbus-rtu: unknown option {short(key)} (known: {', '.join(_RTU_OPTIONS)})"
            if not _RTU_OPTIONS[key](value):
                return f"modbus-rtu: {key}={short(value)} is not allowed"
        return None
    return "expected modbus-tcp://host:port or modbus-rtu://<serial port>?baudrate=N"


def _address_validator(check: Callable[[str], str | None]) -> AfterValidator:
    """Validation of an address field: `auto` (the simulated rig picks it) or what `check` finds no problem with."""
    def validate(address: str) -> str:
        problem = None if address == "auto" else check(address)
        if problem:
            raise ValueError(problem)
        return address
    return AfterValidator(validate)


ModbusAddress = Annotated[str, StringConstraints(min_length=1, max_length=1000),
                          _address_validator(modbus_address_problem)]
SerialAddress = Annotated[str, StringConstraints(min_length=1, max_length=1000),
                          _address_validator(serial_address_problem)]


class DeviceEntry(StrictModel):
    """What every device entry has: the driver's registered name and, for a plug-in, its options."""

    #: The name of rig's own driver for this entry, whose typed keys are the entry's other fields.
    BUILTIN: ClassVar[str]

    driver: str
    #: A plug-in driver's options: every key of the entry but `driver` (a built-in driver takes none).
    options: dict[str, Any] = Field(default_factory=dict)

    @model_validator(mode="before")
    @classmethod
    def _plugin_options(cls, data: Any) -> Any:
        """A plug-in's entry is its name and its own keys: they become its options, unchecked here."""
        if isinstance(data, dict) and data.get("driver", cls.BUILTIN) != cls.BUILTIN:
            options = {key: value for key, value in data.items() if key not in ("driver", "options")}
            return {"driver": data["driver"], "options": {**(data.get("options") or {}), **options}}
        return data

    @model_validator(mode="after")
    def _known_form(self):
        self._check_registered_form()
        return self

    def _check_registered_form(self) -> None:
        """A registered name; rig's own driver with its typed keys only."""
        if not _DRIVER_NAME.fullmatch(self.driver):
            raise ValueError(f"driver {short(self.driver)}: a registered driver name (lower case, digits, -_.); "
                             "`rig devices --list` shows those installed")
        if self.driver == self.BUILTIN and self.options:
            raise ValueError(f"driver {self.BUILTIN} takes no options (its keys are the entry's own)")

    def driver_options(self) -> dict[str, Any]:
        """What the driver's `from_rig` gets besides clock and settings: a built-in's typed keys, a plug-in's
        options."""
        if self.driver != self.BUILTIN:
            return dict(self.options)
        return self.model_dump(exclude={"driver", "options"})


StepsPerDegree = Annotated[float, Field(gt=0, le=1e6)]
DeviceId = Annotated[int, Field(ge=1, le=247)]



#: A Modbus drive's steps per degree when the rig file gives none (the simulated rig's AZ drives).
DRIVE_STEPS_PER_DEGREE = 1000.0

class PositionerDevice(DeviceEntry):
    """Two axes (goniometer arm or sample stage); rig's own driver: two Modbus drives on one link, whose
    registers a drive map names (docs/modbus-drives.md)."""

    BUILTIN = "modbus-drive"
    driver: str = BUILTIN
    #: `modbus-tcp://host:port` or `modbus-rtu://<serial path or pyserial URL>?baudrate=N&parity=E`;
    #: `auto` on the simulated rig (its peers pick free loopback ports).
    address: ModbusAddress = "auto"
    #: A packaged drive map by name, or the path of a map file of the same form.
    map: str = Field("oriental-az", min_length=1, max_length=1000)
    #: The Modbus device ids of the two axes' drives, in the positioner's axis order.
    device_ids: tuple[DeviceId, DeviceId] = (1, 2)
    #: Motor steps per degree of the axis (gearing × resolution): one for both axes, or one each.
    steps_per_degree: StepsPerDegree | tuple[StepsPerDegree, StepsPerDegree] = DRIVE_STEPS_PER_DEGREE
    timeout_s: Seconds = 1.0

    @model_validator(mode="after")
    def _drives(self):
        if self.driver == self.BUILTIN:
            if self.device_ids[0] == self.device_ids[1]:
                raise ValueError(f"device_ids: the two drives need two ids, got {list(self.device_ids)}")
            if not is_map_path(self.map):        # a file is read by load_rig_config, relative to the rig file
                try:
                    load_drive_map(self.map)
                except DriveMapError as exc:
                    raise ValueError(f"map: {exc}") from None
        return self


class LampDevice(DeviceEntry):
    BUILTIN = "delta-sm"
    driver: str = BUILTIN
    address: SerialAddress = "auto"   # e.g. socket://192.168.1.20:8462
    timeout_s: Seconds = 1.0


class MeterDevice(DeviceEntry):
    BUILTIN = "p9710"
    driver: str = BUILTIN
    address: SerialAddress = "auto"   # e.g. /dev/ttyUSB0
    timeout_s: Seconds = 1.0


#: The camera of a served simulated rig (`rig sim serve`), reached over docs/sim-camera-protocol.md.
SERVED_CAMERA = "rig-sim-camera"


class CameraDevice(DeviceEntry):
    """`simulated` (the simulated rig's own camera); a registered camera driver by name, e.g. `lmk` or
    `rig-sim-camera` (a served simulated rig: `address: socket://host:port`), its keys its options; or
    `python:package.module:Class` with `options:` for an unregistered vendor-SDK class (docs/camera-drivers.md).

    Only the form is checked here; rig.devices.check_devices imports and checks the class."""

    BUILTIN = "simulated"
    driver: str = BUILTIN

    @model_validator(mode="after")
    def _known_form(self):
        if self.driver == SERVED_CAMERA:
            address = self.options.get("address")
            problem = serial_address_problem(address) if isinstance(address, str) else "missing"
            if problem or not str(address).startswith("socket://") or set(self.options) != {"address"}:
                raise ValueError(f"camera driver {SERVED_CAMERA} takes exactly options: {{address: socket://host:port}}"
                                 f" (address: {problem or short(str(address))})")
        elif self.driver.startswith("python:"):
            if not re.fullmatch(r"python:[A-Za-z_][\w.]*:[A-Za-z_]\w*", self.driver):
                raise ValueError(f"camera driver {short(self.driver)}: use python:package.module:Class")
        else:
            self._check_registered_form()
        return self


class AttenuatorDevice(DeviceEntry):
    """A motorised neutral-density filter wheel before the camera (rig.acquisition.attenuation); rig's own
    driver is the Thorlabs FW102C/FW212C (docs/fw102c.md). Its filters' transmissions: `attenuator:`."""

    BUILTIN = "fw102c"
    driver: str = BUILTIN
    address: SerialAddress = "auto"   # e.g. /dev/ttyUSB2 (the wheel's USB virtual COM port)
    timeout_s: Seconds = 1.0


class DevicesConfig(StrictModel):
    arm: PositionerDevice = PositionerDevice()
    stage: PositionerDevice = PositionerDevice()
    lamp: LampDevice = LampDevice()
    meter: MeterDevice = MeterDevice()
    camera: CameraDevice = CameraDevice()
    #: Optional: without one, a point whose ROI saturates at the shortest exposure stays a lower bound.
    attenuator: AttenuatorDevice | None = None


#: Axes of each positioner, in controller axis order.
POSITIONER_AXES = {"arm": ("arm_azimuth", "arm_polar"), "stage": ("stage_vertical", "stage_normal")}


