"""Installed drivers: the entry-point group `rig.drivers`, where rig's own drivers register like a lab's.

A package makes a driver available to every rig file on the machine by declaring it
in its metadata (pyproject.toml):

    [project.entry-points."rig.drivers"]
    my-stage = "mylab.stage:MyStage"

The entry's name is the driver's name; the class says its role with a `ROLE`
class attribute (one of ROLES), is checked to implement that role's interface,
and is built from a rig file by its classmethod `from_rig(*, clock, settings,
**options)`: `settings` is the rig file's section for the role (`lamp`, `meter`,
`camera`; for a positioner, its two axes' sections by name, and also `name`), the
options are the device entry's other keys (examples/rig-plugin-example/README.md). Nothing is
imported until a driver is looked at, so one broken package cannot stop the
others from being listed: its entry says what is wrong.
"""

from __future__ import annotations

import inspect
from dataclasses import dataclass
from importlib.metadata import EntryPoint, entry_points
from typing import Any

from rig.drivers.interfaces import Attenuator, IlluminanceMeter, LampSupply, LuminanceCamera

GROUP = "rig.drivers"
#: Roles a driver can fill, and the interface its class must implement (None: checked by its connector).
ROLES: dict[str, type | None] = {"positioner": None, "lamp": LampSupply, "meter": IlluminanceMeter,
                                 "camera": LuminanceCamera, "attenuator": Attenuator}


#: rig's own drivers, exactly as its pyproject.toml registers them (a test holds the two equal): found even
#: when the installed metadata predates them (a checkout updated without reinstalling).
BUILTIN = {"modbus-drive": "rig.drivers.modbus_drive:ModbusDriveLink", "zaber": "rig.drivers.zaber:ZaberChain",
           "delta-sm": "rig.drivers.delta_sm:DeltaSM",
           "p9710": "rig.drivers.p9710:P9710", "lmk": "rig.drivers.lmk:LmkCamera",
           "genicam": "rig.drivers.genicam:GenICamCamera", "fw102c": "rig.drivers.fw102c:FW102C",
           "rig-sim-camera": "rig.drivers.sim_camera:ServedCamera"}


@dataclass(frozen=True)
class InstalledDriver:
    """One entry of the group: its name, the class it names, the package that provides it, and its role
    (or what is wrong with it)."""

    name: str
    target: str
    package: str
    role: str | None
    problem: str | None = None

    def describe(self) -> str:
        what = self.role if self.problem is None else f"unusable: {self.problem}"
        return f"{self.name:16s} {what:12s} {self.target}  ({self.package})"


def _inspect(entry: EntryPoint) -> InstalledDriver:
    dist = entry.dist
    package = f"{dist.name} {dist.version}" if dist is not None else \
        "rig (built in)" if BUILTIN.get(entry.name) == entry.value else "unknown package"
    try:
        cls = entry.load()
    except Exception as exc:      # whatever the plug-in's module raises on import
        return InstalledDriver(entry.name, entry.value, package, None, f"cannot import: {type(exc).__name__}: {exc}")
    role = getattr(cls, "ROLE", None)
    if not inspect.isclass(cls) or role not in ROLES:
        return InstalledDriver(entry.name, entry.value, package, None,
                               f"not a class with ROLE one of {', '.join(ROLES)}")
    interface = ROLES[role]
    if interface is not None and not issubclass(cls, interface):
        return InstalledDriver(entry.name, entry.value, package, role,
                               f"role {role} needs a subclass of {interface.__name__}")
    if not inspect.ismethod(getattr(cls, "from_rig", None)):
        return InstalledDriver(entry.name, entry.value, package, role,
                               "no classmethod from_rig(*, clock, settings, **options)")
    return InstalledDriver(entry.name, entry.value, package, role)


def _entries() -> list[EntryPoint]:
    """The group's entries, and rig's own drivers where the installed metadata lacks them."""
    entries = list(entry_points(group=GROUP))
    names = {entry.name for entry in entries}
    return entries + [EntryPoint(name, target, GROUP) for name, target in BUILTIN.items() if name not in names]


def installed_drivers() -> list[InstalledDriver]:
    """Every entry of the group, sorted by role and name (broken ones last)."""
    found = [_inspect(entry) for entry in _entries()]
    return sorted(found, key=lambda d: (d.problem is not None, d.role or "", d.name))


def driver_class(role: str, name: str) -> Any:
    """The class of the installed driver `name` for `role`; LookupError saying what is installed if there is
    none, or what is wrong with it."""
    for entry in _entries():
        if entry.name == name:
            found = _inspect(entry)
            if found.problem is not None:
                raise LookupError(f"driver {name!r} ({found.package}) cannot be used: {found.problem}")
            if found.role != role:
                raise LookupError(f"driver {name!r} ({found.package}) is a {found.role} driver, not a {role} driver")
            return entry.load()
    raise LookupError(unknown_driver_message(role, name))


def unknown_driver_message(role: str, name: str) -> str:
    """What to say when a rig file names a driver that is not installed for `role`."""
    names = sorted(d.name for d in installed_drivers() if d.role == role and d.problem is None)
    return (f"no {role} driver named {name!r} is installed; installed: {', '.join(names) or '(none)'} "
            f"(`rig devices --list` shows every driver and its package)")
