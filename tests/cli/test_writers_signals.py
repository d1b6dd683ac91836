"""SIGTERM and SIGHUP end `rig plot` and `rig export --format radiance-xml` the way Ctrl+C does: no half-written
output, no `rig-radiance-*` temporary folder, no Radiance tool (nor its children) left running, and the rerun
is not refused (issue 30, item 8). Real `rig` processes, signalled while they write.

The export runs stand-in Radiance tools (a `pyradiance` whose BINPATH holds shell scripts): each starts a child
of its own, as bsdf2ttree starts rttree_reduce, writes both process ids and waits, so the signal always lands
while the tool runs; with RIG_FAKE_FAST set they print a line and exit at once.
"""

import os
import signal
import subprocess
import sys
import time
import types
from pathlib import Path

import pytest

from rig.cli.main import main
from rig.core.interrupts import Interrupted, held_signals, interruptible, signals_interrupt
from rig.data.output_folder import require_new_output
from rig_process import POLL_S, start_rig, wait_until

TOOL = """#!/bin/sh
if [ -n "$RIG_FAKE_FAST" ]; then echo "output of $0"; exit 0; fi
sleep 300 &
echo "$$ $!" > "$RIG_FAKE_PIDS.tmp" && mv "$RIG_FAKE_PIDS.tmp" "$RIG_FAKE_PIDS"
wait
"""


@pytest.fixture(scope="module")
def tape(cea_dir, tmp_path_factory) -> Path:
    """Three incidences of the gray tape, every 60th point, imported."""
    folder = tmp_path_factory.mktemp("tape")
    lines = (cea_dir / "retro-gray-tape.alta").read_text().splitlines()
    head, data = [x for x in lines if x.startswith("#")], [x for x in lines if x and not x.startswith("#")]
    (folder / "t.alta").write_text("\n".join(head + data[::60]) + "\n")
    assert main(["import", str(folder / "t.alta"), "--out", str(folder / "ds")]) == 0
    return folder / "ds"


def _ended(proc: subprocess.Popen) -> str:
    try:
        _, err = proc.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        proc.kill()
        pytest.fail("rig did not end after the signal")
    return err


@pytest.mark.parametrize("sig", [signal.SIGTERM])
def test_a_signal_mid_plot_removes_the_figures(tape, tmp_path, sig):
    out = tmp_path / "figures"
    proc = start_rig("plot", str(tape), "--out", str(out))
    wait_until(lambda: any(tmp_path.glob(".figures.*/*.png")), proc, "the first figure (in the temporary folder)")
    proc.send_signal(sig)
    err = _ended(proc)
    assert proc.returncode == 128 + sig, err
    assert f"stopped by {signal.Signals(sig).name}" in err and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []                                # neither --out nor the temporary folder
    require_new_output(out)              # what refused the rerun: an --out that is not empty


def test_a_kill_mid_plot_leaves_no_out_to_refuse_the_rerun(tape, tmp_path):
    """SIGKILL cannot be cleaned up after: the figures are drawn in a hidden folder renamed when complete, so
    `--out` does not exist and the rerun is accepted."""
    out = tmp_path / "figures"
    proc = start_rig("plot", str(tape), "--out", str(out))
    wait_until(lambda: any(tmp_path.glob(".figures.*/*.png")), proc, "the first figure (in the temporary folder)")
    proc.kill()
    _ended(proc)
    assert not out.exists()
    require_new_output(out)


@pytest.fixture
def fake_radiance(tmp_path) -> dict[str, str]:
    """The environment of a `rig` whose pyradiance runs the stand-in tools, and whose temporary folders go to
    tmp_path/tmp."""
    bin_dir, package = tmp_path / "radiance-bin", tmp_path / "site" / "pyradiance"
    bin_dir.mkdir()
    package.mkdir(parents=True)
    (package / "__init__.py").write_text(f"BINPATH = {str(bin_dir)!r}\n")
    for tool in ("pabopto2bsdf", "bsdf2ttree"):
        (bin_dir / tool).write_text(TOOL)
        (bin_dir / tool).chmod(0o755)
    (tmp_path / "tmp").mkdir()
    return {"PYTHONPATH": os.pathsep.join([str(tmp_path / "site"), os.environ.get("PYTHONPATH", "")]),
            "TMPDIR": str(tmp_path / "tmp"), "RIG_FAKE_PIDS": str(tmp_path / "pids")}


def _kill(*pids: int) -> None:
    """Kill what is left of the stand-in tools (checked by command line: a process id may have been reused)."""
    for pid in pids:
        try:
            cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
        except FileNotFoundError:
            continue
        if not _gone(pid) and (b"radiance-bin" in cmdline or cmdline == b"sleep\x00300\x00"):
            os.kill(pid, signal.SIGKILL)


def _gone(pid: int) -> bool:
    """The process has ended (a zombie waiting for a parent that does not reap counts as ended)."""
    try:
        return Path(f"/proc/{pid}/status").read_text().split("State:")[1].split()[0] == "Z"
    except (FileNotFoundError, IndexError):
        return True


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGHUP])
def test_a_signal_mid_radiance_xml_leaves_no_debris(tape, tmp_path, fake_radiance, sig, monkeypatch, request):
    out, pids = tmp_path / "sample.xml", Path(fake_radiance["RIG_FAKE_PIDS"])
    # --anisotropic: the measured series as they are, no reconstruction before the tools run (a quicker test)
    argv = ["export", str(tape), "--format", "radiance-xml", "--anisotropic", "--out", str(out)]
    proc = start_rig(*argv, env=fake_radiance)
    wait_until(pids.exists, proc, "pabopto2bsdf running")
    tool, child = (int(p) for p in pids.read_text().split())
    request.addfinalizer(lambda: _kill(tool, child))                     # if the test fails: no sleeper left
    proc.send_signal(sig)
    err = _ended(proc)
    assert proc.returncode == 128 + sig, err
    assert "Traceback" not in err
    assert list(tmp_path.glob("*sample.xml*")) == []                     # neither the output nor its temporary file
    assert list((tmp_path / "tmp").iterdir()) == []                      # no rig-radiance-* folder
    for _ in range(5000):                                                # a killed process may take a moment to go
        if _gone(tool) and _gone(child):
            break
        time.sleep(POLL_S)
    assert _gone(tool) and _gone(child)
    # the rerun, in this process: the same stand-in tools, quick this time
    monkeypatch.setitem(sys.modules, "pyradiance", types.SimpleNamespace(BINPATH=str(tmp_path / "radiance-bin")))
    monkeypatch.setenv("RIG_FAKE_FAST", "1")
    assert main(argv) == 0
    assert out.read_text().startswith("output of ") and "bsdf2ttree" in out.read_text()


def test_a_signal_inside_held_signals_is_raised_at_its_end():
    """The one step that must not be cut (a child started, its handle not yet kept) gets the signal after it."""
    steps = []
    with pytest.raises(Interrupted) as caught, signals_interrupt():
        with held_signals():
            os.kill(os.getpid(), signal.SIGTERM)
            steps.append("the step finished")
        steps.append("not reached")
    assert steps == ["the step finished"] and caught.value.signum == signal.SIGTERM


def test_an_interruptible_command_says_which_signal_and_exits_128_plus_it(capsys):
    @interruptible
    def command(args) -> int:
        os.kill(os.getpid(), signal.SIGHUP)
        return 0

    assert command(None) == 128 + signal.SIGHUP
    assert capsys.readouterr().err == "rig: stopped by SIGHUP; nothing unfinished was left behind\n"
