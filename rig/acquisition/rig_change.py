"""Whether a new rig file describes the instruments a dataset was measured with (`rig run --resume DIR --rig NEW`).

A resume continues one measurement, so everything that says which instruments took it and what its numbers
mean must be the same: drivers and roles, device ids, drive maps, a plug-in's options (a camera's serial or
model), geometry, axes, the camera, lamp and meter sections with their calibrations, the filters. What may
differ is how each device is reached — its address (a served rig restarted on new ports, a USB serial adapter
back under another name) and its link's timeout — which says nothing about the data. Files the rig file
names (a drive map, a camera calibration file) are compared by content: the new rig file may sit in another
folder than the first one.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from rig.config.rigfile import RigConfig

#: The keys of a device entry (or of a plug-in's options) that say how the device is reached.
LINK_KEYS = ("address", "timeout_s")
#: Keys whose values name files, relative to the rig file when it was loaded.
_FILE_KEYS = {("devices", "arm", "map"), ("devices", "stage", "map"), ("camera", "calibration_file")}
_ABSENT = object()


def _flatten(data: Any, prefix: tuple[str, ...] = ()) -> dict[tuple[str, ...], Any]:
    """Every leaf of a JSON-like tree by its key path (an empty mapping is a leaf)."""
    if isinstance(data, dict) and data:
        leaves: dict[tuple[str, ...], Any] = {}
        for key, value in data.items():
            leaves.update(_flatten(value, (*prefix, str(key))))
        return leaves
    return {prefix: data}


def _is_link(key: tuple[str, ...]) -> bool:
    """devices.<device>.address / timeout_s, or the same keys among a plug-in's options."""
    return key[0] == "devices" and key[-1] in LINK_KEYS and (len(key) == 3 or (len(key) == 4 and key[2] == "options"))


def _same_file(a: Any, b: Any) -> bool:
    if a == b:
        return True
    if not (isinstance(a, str) and isinstance(b, str)):
        return False
    try:
        return Path(a).read_bytes() == Path(b).read_bytes()
    except OSError:                 # a packaged map's name, or a file gone: compared by name, which differs
        return False


def _leaves(config: RigConfig) -> dict[tuple[str, ...], Any]:
    return _flatten(config.model_dump(mode="json"))


def _shown(value: Any) -> str:
    return "absent" if value is _ABSENT or value is None else repr(value)


def instrument_difference(recorded: RigConfig, new: RigConfig) -> str | None:
    """The first key, outside how the devices are reached, in which `new` differs from `recorded`; None if
    they describe the same instruments."""
    old_leaves, new_leaves = _leaves(recorded), _leaves(new)
    for key in [*old_leaves, *(k for k in new_leaves if k not in old_leaves)]:
        if _is_link(key):
            continue
        a, b = old_leaves.get(key, _ABSENT), new_leaves.get(key, _ABSENT)
        if key in _FILE_KEYS and isinstance(a, str) and isinstance(b, str):
            if not _same_file(a, b):
                return f"key '{'.'.join(key)}': {b} is not the file the dataset's rig named ({a}), nor a copy of it"
        elif a != b:
            return f"key '{'.'.join(key)}' is {_shown(b)}, the dataset's rig had {_shown(a)}"
    return None


def link_changes(recorded: RigConfig, new: RigConfig) -> dict[str, list[Any]]:
    """How the devices are reached, where `new` differs from `recorded`: {key: [recorded, new]}."""
    old_leaves, new_leaves = _leaves(recorded), _leaves(new)
    return {".".join(key): [old_leaves.get(key), new_leaves.get(key)]
            for key in [*old_leaves, *(k for k in new_leaves if k not in old_leaves)]
            if _is_link(key) and old_leaves.get(key) != new_leaves.get(key)}
