"""README.md says "The outputs shown are real, from the simulated rig": its console transcripts are replayed here
and each line it shows must be a line the command prints, in order, so that a change to what a command prints (or
to what it measures) cannot leave the README showing something else. The README's own `…` elides lines; a progress
bar line (`[###…]`) depends on the terminal and is not compared.

Replayed: the commands that need neither a network nor seconds of plotting (`rig devices --check`, `rig devices`
on the simulated rig, `rig plan`, `rig run`, `rig fit`, `rig export`), in a fresh folder laid out as the README's
steps leave it (the example lab's rig file copied to rigs/my-lab.yaml, the quick campaign to my-sample.yaml). What
differs from machine to machine by nature is masked: loopback ports and wall times. Numbers are compared to the
digits the README prints (a last-digit difference of a fit across machines passes; a shift of 1e-4 does not).
"""

import re
import shlex
import shutil

import pytest

from repo_paths import CAMPAIGNS, RIGS, ROOT
from rig.cli.main import main

#: The README's commands replayed here (the others: a browser, plotting, reports, tested elsewhere).
REPLAYED = ("rig devices", "rig plan", "rig run", "rig fit", "rig export")
NUMBER = re.compile(r"\d+(?:\.(\d+))?(?:e[-+]?\d+)?")
MASKS = [(re.compile(r"(127\.0\.0\.1):\d+"), r"\1:<port>"), (re.compile(r"wall time [\d.]+ s"), "wall time <s>")]


def transcripts(readme: str) -> list[tuple[str, list[str]]]:
    """(command, the lines the README shows it print) of every `$ rig …` line of its console blocks."""
    shown: list[tuple[str, list[str]]] = []
    for block in re.findall(r"```console\n(.*?)```", readme, re.S):
        for line in block.splitlines():
            if line.startswith("$ "):
                shown.append((line[2:], []))
            elif shown:
                shown[-1][1].append(line)
    return shown


def masked(line: str) -> str:
    for pattern, repl in MASKS:
        line = pattern.sub(repl, line)
    return " ".join(line.split())


def same_line(shown: str, printed: str) -> bool:
    """The same words, and each number equal to the digits the README gives it (half a unit of its last digit,
    and at least 1e-4 of it)."""
    shown, printed = masked(shown), masked(printed)
    if NUMBER.sub("#", shown) != NUMBER.sub("#", printed):
        return False
    for a, b in zip(NUMBER.finditer(shown), NUMBER.finditer(printed)):
        digits = len(a.group(1) or "") if "e" not in a.group(0) else 3
        value = float(a.group(0))
        if abs(float(b.group(0)) - value) > max(0.5 * 10.0 ** -digits, 1e-4 * abs(value)):
            return False
    return True


def missing_lines(shown: list[str], printed: list[str]) -> list[str]:
    """The README's lines (but `…` and a progress bar) that the command did not print, in the README's order."""
    missing, at = [], 0
    for line in shown:
        if line.strip() in ("", "…") or line.lstrip().startswith("["):
            continue
        found = next((k for k in range(at, len(printed)) if same_line(line, printed[k])), None)
        if found is None:
            missing.append(line)
        else:
            at = found + 1
    return missing


def test_a_line_with_other_numbers_or_words_is_not_the_same():
    """The comparison fails where it should: a fit value moved by 2e-4, a count, a word; masks hide what varies."""
    assert same_line("  kd           0.620008  ± 0.00045  (0.07%)", "  kd  0.620009 ± 0.00045 (0.07%)")
    assert not same_line("  kd           0.620008  ± 0.00045  (0.07%)", "  kd  0.620132 ± 0.00045 (0.07%)")
    assert not same_line("complete: 62 points measured", "complete: 61 points measured")
    assert not same_line("complete: 62 points measured", "failed: 62 points measured")
    assert same_line("rig time 0:15:33, wall time 5.4 s", "rig time 0:15:33, wall time 1.0 s")
    assert same_line("Modbus id 1 at modbus-tcp://127.0.0.1:41403", "Modbus id 1 at modbus-tcp://127.0.0.1:5020")
    assert missing_lines(["a 1", "…", "b 2"], ["a 1", "x", "b 2"]) == []
    assert missing_lines(["b 2", "a 1"], ["a 1", "b 2"]) == ["a 1"]              # order counts


def test_the_readme_shows_what_the_commands_print(tmp_path, monkeypatch, capsys):
    (tmp_path / "rigs").mkdir()
    shutil.copy(RIGS / "example-lab.yaml", tmp_path / "rigs" / "my-lab.yaml")
    shutil.copy(CAMPAIGNS / "quick.yaml", tmp_path / "my-sample.yaml")
    shutil.copytree(CAMPAIGNS, tmp_path / "campaigns")
    monkeypatch.chdir(tmp_path)
    replayed = [(command, shown) for command, shown in transcripts((ROOT / "README.md").read_text(encoding="utf-8"))
                if command.startswith(REPLAYED)]
    assert [c.split()[1] for c, _ in replayed] == ["devices", "devices", "plan", "run", "fit", "export"]
    for command, shown in replayed:
        capsys.readouterr()
        code = main(shlex.split(command)[1:])
        out = capsys.readouterr()
        printed = (out.out + out.err).splitlines()
        assert code == 0, f"{command}: exit {code}\n{out.err}"
        missing = missing_lines(shown, printed)
        assert not missing, f"{command}: the README shows {missing}, but it printed:\n" + "\n".join(printed)


@pytest.fixture(autouse=True)
def _quick_run_is_not_paced(monkeypatch):
    """`rig run` on the simulated rig as fast as it goes (a pacing variable in the environment would slow it)."""
    monkeypatch.delenv("RIG_SIM_PACE", raising=False)
