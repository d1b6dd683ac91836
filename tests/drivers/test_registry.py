"""Installed drivers (entry-point group `rig.drivers`): rig's own register like a plug-in; broken entries
are listed with what is wrong, not fatal to the listing."""

from __future__ import annotations

from importlib.metadata import EntryPoint

from rig.cli.main import main
from rig.drivers import registry
from rig.drivers.registry import GROUP, installed_drivers, unknown_driver_message

PLUGIN = '''
from rig.drivers.interfaces import LampSupply

class NoRole:
    pass

class WrongInterface:
    ROLE = "lamp"

class Pretender(LampSupply):
    @classmethod
    def from_rig(cls, *, clock, settings, address):
        return cls()

class NoContract(LampSupply):
    pass

raise_on_import = False
'''


def test_rigs_own_drivers_are_installed_with_their_roles():
    found = {d.name: d for d in installed_drivers()}
    expected = {"modbus-drive": "positioner", "zaber": "positioner", "delta-sm": "lamp", "p9710": "meter",
                "lmk": "camera", "genicam": "camera", "rig-sim-camera": "camera", "fw102c": "attenuator"}
    for name, role in expected.items():
        assert found[name].role == role and found[name].problem is None, found[name]
        assert found[name].package.startswith("rig ")


def test_broken_entries_are_listed_with_what_is_wrong(tmp_path, monkeypatch):
    (tmp_path / "labplugin.py").write_text(PLUGIN)
    (tmp_path / "brokenplugin.py").write_text("raise RuntimeError('vendor SDK missing')\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    entries = [EntryPoint("no-role", "labplugin:NoRole", GROUP), EntryPoint("wrong", "labplugin:WrongInterface", GROUP),
               EntryPoint("broken", "brokenplugin:Camera", GROUP), EntryPoint("keithley", "labplugin:Pretender", GROUP),
               EntryPoint("half", "labplugin:NoContract", GROUP)]
    monkeypatch.setattr(registry, "entry_points", lambda group: entries if group == GROUP else [])
    found = {d.name: d for d in installed_drivers()}
    assert "ROLE one of positioner, lamp" in found["no-role"].problem
    assert "needs a subclass of LampSupply" in found["wrong"].problem
    assert "RuntimeError: vendor SDK missing" in found["broken"].problem
    assert "no classmethod from_rig" in found["half"].problem
    assert found["keithley"].role == "lamp" and found["keithley"].problem is None
    assert found["keithley"].package == "unknown package"
    problems = [d.problem is not None for d in installed_drivers()]
    assert problems == sorted(problems)                  # the usable ones first
    assert "installed: delta-sm, keithley" in unknown_driver_message("lamp", "sorensen")   # rig's own too


def test_unknown_name_lists_what_is_installed_for_the_role():
    message = unknown_driver_message("meter", "keithley-6485")
    assert "no meter driver named 'keithley-6485'" in message and "installed: p9710" in message
    assert "rig devices --list" in message


def test_rig_devices_list_prints_every_driver_with_role_and_package(capsys):
    assert main(["devices", "--list"]) == 0
    out = capsys.readouterr().out
    assert "delta-sm" in out and "lamp" in out and "rig 0.1" in out


def test_rig_devices_needs_a_rig_file_or_list(capsys):
    assert main(["devices"]) == 2
    assert "give a rig file, or --list" in capsys.readouterr().err



def test_the_built_in_table_is_what_pyproject_registers():
    import tomllib

    from repo_paths import ROOT

    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert project["entry-points"][GROUP] == registry.BUILTIN
