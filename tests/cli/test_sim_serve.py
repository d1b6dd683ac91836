"""`rig sim serve` + `rig run --rig`: the simulated rig as a standalone instrument server, driven like
hardware from other processes; a client killed with SIGKILL leaves the lamp to the supply's watchdog.

Everything runs as real processes over the real protocol stacks (Modbus/TCP, SCPI over TCP, the meter
on a pseudo-terminal, the camera protocol of docs/sim-camera-protocol.md). Waits are bounded by
rig_process.HANG_S as a hang guard, never asserted on.
"""

from __future__ import annotations

import csv
import errno
import json
import os
import re
import signal
import socket
import stat
import subprocess
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
import yaml

from repo_paths import CAMPAIGNS, TEST_CAMPAIGNS
from rig.cli.main import main
from rig.config.campaign import load_campaign
from rig.config.rigfile import load_rig_config
from rig.simulators.served import PAPER_RM1, ServedRig
from rig_process import HANG_S, pending_points, start_rig, wait_until

CAMPAIGN = TEST_CAMPAIGNS / "served.yaml"
#: Rig seconds per wall second of the served world: the campaign's ~1.3 min of rig time take ~15 s, long
#: enough for a second client to start while it runs (~3 s of imports), while the 10 s watchdog still leaves
#: the client two seconds of wall time between two lamp commands.
SPEED = 5.0
WATCHDOG_S = 10.0


@contextmanager
def serving(folder: Path, name: str = "served-rig", speed: float = SPEED) -> Iterator[tuple[Path, Path,
                                                                                        subprocess.Popen]]:
    """A running `rig sim serve` (its rig file `<name>.yaml`, its stderr log, the process); stopped with SIGTERM
    afterwards."""
    base = folder / "base-rig.yaml"
    base.write_text(yaml.safe_dump({"name": "bench", "lamp": {"watchdog_s": WATCHDOG_S}}))
    rig_file, log = folder / f"{name}.yaml", folder / f"{name}.log"
    with log.open("w") as err:
        server = start_rig("sim", "serve", "--rig-file", str(rig_file), "--rig", str(base),
                           "--campaign", str(CAMPAIGN), "--speed", str(speed), stderr=err)
    try:
        wait_until(rig_file.exists, server, "the served rig file")
        yield rig_file, log, server
    finally:
        server.send_signal(signal.SIGTERM)
        try:
            out, _ = server.communicate(timeout=HANG_S)
        except subprocess.TimeoutExpired:
            server.kill()
            pytest.fail("rig sim serve did not stop on SIGTERM")
    assert server.returncode == 0, log.read_text()
    assert "stopped" in out
    assert not rig_file.exists()            # its addresses died with it


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[Path, Path, subprocess.Popen]]:
    with serving(tmp_path) as server:
        yield server


def scpi(address: str, line: str) -> str:
    """One SCPI query to the served lamp supply, as a separate client would send it."""
    host, port = address.removeprefix("socket://").rsplit(":", 1)
    with socket.create_connection((host, int(port)), timeout=HANG_S) as conn:
        conn.sendall(line.encode() + b"\n")
        reply = b""
        while not reply.endswith(b"\n"):
            chunk = conn.recv(100)
            assert chunk, f"the supply closed the connection instead of answering {line!r}"
            reply += chunk
    return reply.decode().strip()


def brdf_rows(folder: Path) -> list[dict[str, str]]:
    with (folder / "brdf.csv").open() as f:
        return list(csv.DictReader(f))


def test_the_served_rig_file_is_hardware_to_its_clients(served):
    rig_file, _, _ = served
    rig = load_rig_config(rig_file)
    assert not rig.simulated and rig.time_scale == pytest.approx(SPEED)
    assert rig.lamp.watchdog_s == pytest.approx(WATCHDOG_S)
    assert rig.devices.lamp.address.startswith("socket://127.0.0.1:")
    assert rig.devices.arm.address.startswith("modbus-tcp://127.0.0.1:")
    assert rig.devices.meter.address.startswith("/dev/")
    assert rig.devices.camera.driver == "rig-sim-camera"
    assert "simulation" not in yaml.safe_load(rig_file.read_text())
    devices = start_rig("devices", str(rig_file))
    out, err = devices.communicate(timeout=HANG_S)
    assert devices.returncode == 0, err
    assert "hardware" in out and "DELTA ELEKTRONIKA" in out.upper()


def test_kill_9_leaves_the_lamp_to_the_watchdog_and_resume_completes(served, tmp_path):
    rig_file, log, server = served
    lamp = load_rig_config(rig_file).devices.lamp.address
    out = tmp_path / "run"
    run = start_rig("run", str(CAMPAIGN), "--rig", str(rig_file), "--out", str(out), "--quiet")
    wait_until(lambda: pending_points(out) >= 2, run, "two points measured")

    # A second client while the campaign runs is refused, before it touches any device.
    second = start_rig("devices", str(rig_file))
    _, err = second.communicate(timeout=HANG_S)
    assert second.returncode == 1 and re.search(r"busy|in use", err, re.I), err
    assert run.poll() is None, "the first client must not notice the second"

    run.send_signal(signal.SIGKILL)                  # no exit path runs: the lamp stays on ...
    run.wait(timeout=HANG_S)
    wait_until(lambda: "watchdog" in log.read_text(), server, "the watchdog switching the lamp off")
    assert scpi(lamp, "OUTPut?") == "0"              # ... until the supply's watchdog switches it off
    off = re.search(r"watchdog at rig time [\d.]+ s, ([\d.]+) s after the last command", log.read_text())
    assert off is not None, log.read_text()
    # Off when the watchdog time was up, give or take the server loop's tick (5 ms of wall time, 0.05 s of rig
    # time at this speed) and a loaded machine's scheduling.
    assert WATCHDOG_S <= float(off.group(1)) <= WATCHDOG_S + 1.0

    resume = start_rig("run", "--resume", str(out), "--quiet")
    _, err = resume.communicate(timeout=HANG_S)
    assert resume.returncode == 0, err
    manifest = json.loads((out / "dataset.json").read_text())
    ids = [row["point_id"] for row in brdf_rows(out)]
    assert len(ids) == len(set(ids)), "a point was written twice"
    assert manifest["status"] == "complete"
    assert len(ids) == manifest["counts"]["planned"] == manifest["counts"]["measured"] == 16
    assert scpi(lamp, "OUTPut?") == "0"              # a clean end switched it off and disarmed the watchdog
    assert scpi(lamp, "SYSTem:COMmunicate:WATchdog?") == "-1"


def test_a_run_refused_as_busy_leaves_no_dataset_folder(served, tmp_path):
    """Before: the refused `rig run` left a `failed` dataset folder with no point, which its rerun refused."""
    rig_file, _, _ = served
    host, port = load_rig_config(rig_file).devices.camera.options["address"].removeprefix("socket://").rsplit(":", 1)
    with socket.create_connection((host, int(port)), timeout=HANG_S) as holder:     # another client's session
        holder.sendall(b"HELLO rig-sim-camera/1\n")
        assert holder.recv(200).startswith(b"OK rig-sim-camera/1")
        out = tmp_path / "second"
        refused = start_rig("run", str(CAMPAIGN), "--rig", str(rig_file), "--out", str(out), "--quiet")
        _, err = refused.communicate(timeout=HANG_S)
    assert refused.returncode == 1 and "busy" in err and "nothing was written" in err, err
    assert not out.exists()


def test_resume_after_a_server_restart_on_new_ports_uses_the_new_rig_file(tmp_path):
    """Issue 30 item 4. Before: `--rig` was ignored, the resume dialled the old server's ports and failed with
    "0 completed points kept"."""
    out = tmp_path / "run"
    with serving(tmp_path, "first", speed=20.0) as (first, _, _):
        run = start_rig("run", str(CAMPAIGN), "--rig", str(first), "--out", str(out), "--quiet")
        wait_until(lambda: pending_points(out) >= 2, run, "two points measured")
        run.send_signal(signal.SIGINT)                  # the point in flight finished, lamp off
        assert run.wait(timeout=HANG_S) == 130
        old = load_rig_config(first)
    kept = [row["point_id"] for row in brdf_rows(out)]
    assert len(kept) >= 2
    with serving(tmp_path, "second", speed=20.0) as (second, _, _):
        new = load_rig_config(second)
        assert new.devices.lamp.address != old.devices.lamp.address
        resume = start_rig("run", "--resume", str(out), "--rig", str(second), "--quiet")
        _, err = resume.communicate(timeout=HANG_S)
    assert resume.returncode == 0, err
    manifest = json.loads((out / "dataset.json").read_text())
    ids = [row["point_id"] for row in brdf_rows(out)]
    assert ids[:len(kept)] == kept and len(ids) == len(set(ids)) == manifest["counts"]["planned"] == 16
    assert manifest["status"] == "complete"
    assert manifest["resumes"][-1]["rig_file"] == str(second.resolve())
    assert manifest["rig"]["config"]["devices"]["lamp"]["address"] == new.devices.lamp.address
    resumed = [json.loads(line) for line in (out / "events.jsonl").read_text().splitlines()
               if '"resume"' in line][-1]
    changes = resumed["rig_changes"]
    assert changes["devices.lamp.address"] == [old.devices.lamp.address, new.devices.lamp.address]
    assert changes["devices.camera.options.address"][1] == new.devices.camera.options["address"]
    assert set(changes) <= {f"devices.{d}.address" for d in ("arm", "stage", "lamp", "meter")} | {
        "devices.camera.options.address"}


def test_the_default_sample_is_the_paper_campaigns_rm1():
    truth = load_campaign(CAMPAIGNS / "spieringhs2023-rm1.yaml").sample.simulated_brdf
    assert truth is not None and (truth.model, truth.params) == (PAPER_RM1[0], pytest.approx(PAPER_RM1[1]))


@pytest.mark.parametrize("args, message", [
    (["--speed", "0"], "--speed 0: must be above 0"),
    (["--speed", "5000"], "at most 1000"),
    (["--campaign", "nowhere.yaml"], "nowhere.yaml"),
])
def test_bad_serve_options_are_refused_before_serving(tmp_path, args, message):
    proc = start_rig("sim", "serve", "--rig-file", str(tmp_path / "r.yaml"), *args)
    _, err = proc.communicate(timeout=HANG_S)
    assert proc.returncode == 2 and message in err, err
    assert not (tmp_path / "r.yaml").exists()


def test_a_rig_file_in_a_missing_folder_is_refused(tmp_path):
    proc = start_rig("sim", "serve", "--rig-file", str(tmp_path / "no" / "r.yaml"))
    _, err = proc.communicate(timeout=HANG_S)
    assert proc.returncode == 2 and "does not exist" in err, err


# -- issue 30 item 2: nothing that is already at --rig-file is overwritten or removed ---------------------------

def _occupy(path: Path, kind: str) -> None:
    """Put something of `kind` at `path`: what a lab may have there (its own rig file, a link, a pipe)."""
    if kind == "file":
        path.write_text("name: the lab's own rig file\n")
    elif kind == "symlink":
        path.parent.joinpath("target.yaml").write_text("kept\n")
        path.symlink_to("target.yaml")
    elif kind == "dangling symlink":
        path.symlink_to("nowhere.yaml")
    elif kind == "fifo":
        os.mkfifo(path)
    else:
        path.mkdir()


def _must_not_serve(self: ServedRig) -> None:
    raise AssertionError("refused before serving: nothing may be written to the path")


def _snapshot(path: Path) -> tuple:
    found = os.lstat(path)
    content = path.read_text() if stat.S_ISREG(found.st_mode) else None
    return found.st_mode, found.st_ino, found.st_mtime_ns, content, os.readlink(path) if path.is_symlink() else None


@pytest.mark.parametrize("kind, what", [("file", "a file"), ("symlink", "a symbolic link"),
                                        ("dangling symlink", "a symbolic link"), ("fifo", "a FIFO"),
                                        ("folder", "a folder")])
def test_whatever_is_at_the_rig_file_path_is_refused_and_left_alone(tmp_path, capsys, monkeypatch, kind, what):
    """Before: the path was replaced by the served rig file (a FIFO or a device became a regular file), then
    removed on exit."""
    monkeypatch.setattr(ServedRig, "start", _must_not_serve)
    path = tmp_path / "rig.yaml"
    _occupy(path, kind)
    before = _snapshot(path)
    assert main(["sim", "serve", "--rig-file", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"rig: error: --rig-file {path}: {what} is already there"), err
    assert _snapshot(path) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["rig.yaml"] + (["target.yaml"] * (kind == "symlink")))


def test_only_the_file_it_wrote_is_removed_on_exit(tmp_path):
    """The server removes its own rig file on exit, not one that has replaced it since (same name, other inode)."""
    rig_file = tmp_path / "served.yaml"
    server = start_rig("sim", "serve", "--rig-file", str(rig_file))
    try:
        wait_until(rig_file.exists, server, "the served rig file")
        assert load_rig_config(rig_file).devices.lamp.address.startswith("socket://127.0.0.1:")
        assert [p.name for p in tmp_path.iterdir()] == ["served.yaml"]      # no temporary file left beside it
        replacement = tmp_path / "edited.yaml"
        replacement.write_text("name: mine now\n")
        replacement.replace(rig_file)                                        # the lab's edit, saved over it
    finally:
        server.send_signal(signal.SIGTERM)
        server.communicate(timeout=HANG_S)
    assert server.returncode == 0
    assert rig_file.read_text() == "name: mine now\n"


def test_a_file_system_without_hard_links_is_one_message(tmp_path, capsys, monkeypatch):
    """The file is linked into place (exclusive and atomic); where links are refused, exit 2 and nothing left."""
    def refuse(src, dst):
        raise OSError(errno.EPERM, "Operation not permitted")
    monkeypatch.setattr(os, "link", refuse)
    assert main(["sim", "serve", "--rig-file", str(tmp_path / "r.yaml")]) == 2
    assert f"--rig-file {tmp_path / 'r.yaml'}: cannot write it there: Operation not permitted" in \
        capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
