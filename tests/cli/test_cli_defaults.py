"""The command line for someone at the rig (issue 35, item 5): every subcommand and option says what it is in
`--help`, a second `rig run` of a campaign without --out measures into a new folder instead of refusing, and a
busy port in `rig monitor` is bad input (exit 2, as the README's exit codes say), naming the port."""

import argparse
import socket
from datetime import datetime
from pathlib import Path

import pytest

from rig.cli.main import build_parser, main
from rig.data.output_folder import default_output

TINY = """name: tiny
sample: {id: T1, simulated_brdf: {model: lambert, params: {kd: 0.5}}}
incidence: [{phi: 0, theta: [30]}]
viewing: [{centred_on: incidence, theta: [10], phi: [90, 270]}]
output: {dir: runs/tiny}
lamp: {warmup_min_s: 60}
"""


def _parsers(parser: argparse.ArgumentParser, name: str = "rig"):
    """Every (sub)command's parser, with its name."""
    yield name, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub, child in action.choices.items():
                yield from _parsers(child, f"{name} {sub}")


def test_every_subcommand_and_option_has_help(capsys):
    parser = build_parser()
    seen = 0
    for name, p in _parsers(parser):
        for action in p._actions:
            if isinstance(action, argparse._SubParsersAction):
                assert all(c.help for c in action._choices_actions), name
                assert {c.dest for c in action._choices_actions} == set(action.choices), name
            elif not isinstance(action, (argparse._HelpAction, argparse._VersionAction)):
                assert action.help and action.help.strip(), f"{name}: {action.option_strings or action.dest}"
        with pytest.raises(SystemExit) as exit_:
            main([*name.split()[1:], "--help"])
        assert exit_.value.code == 0 and capsys.readouterr().out.startswith(f"usage: {name}")
        seen += 1
    assert seen >= 17          # rig, its 13 commands, and the bench, sim and calibrate subcommands


def test_default_output_is_the_campaign_folder_while_free_then_stamped(tmp_path):
    base = tmp_path / "runs" / "quick"
    assert default_output(base) == base                           # absent
    base.mkdir(parents=True)
    assert default_output(base) == base                           # empty
    (base / "brdf.csv").write_text("x")
    now = datetime(2026, 11, 28, 1, 2, 3)
    assert default_output(base, now) == tmp_path / "runs" / "quick-20261128-010203"
    (tmp_path / "runs" / "quick-20261128-010203").mkdir()
    assert default_output(base, now) == tmp_path / "runs" / "quick-20261128-010203-2"


def test_a_second_run_without_out_measures_into_a_new_folder(tmp_path, monkeypatch, capsys):
    """runs/tiny holds a first run's dataset (a stand-in: only its being taken matters)."""
    monkeypatch.chdir(tmp_path)
    Path("tiny.yaml").write_text(TINY)
    (tmp_path / "runs" / "tiny").mkdir(parents=True)
    (tmp_path / "runs" / "tiny" / "brdf.csv").write_text("a first run\n")
    assert main(["run", "tiny.yaml", "--quiet"]) == 0, capsys.readouterr().err
    (second,) = [p for p in (tmp_path / "runs").iterdir() if p.name != "tiny"]
    assert second.name.startswith("tiny-20") and (second / "brdf.csv").exists()
    assert f"→ runs/{second.name} (" in capsys.readouterr().err
    # an explicit --out that is taken is still refused, saying what to do
    assert main(["run", "tiny.yaml", "--quiet", "--out", "runs/tiny"]) == 2
    assert "choose another --out" in capsys.readouterr().err


def test_monitor_on_a_busy_port_is_bad_input(tmp_path, capsys):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        assert main(["monitor", str(tmp_path), "--port", str(port)]) == 2
    err = capsys.readouterr().err
    assert f"port {port}" in err and "--port" in err and "Traceback" not in err
