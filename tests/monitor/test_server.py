"""`rig monitor` over HTTP on loopback: the JSON and its increments, the page's files, the token on
other addresses, the refusals at start, Ctrl+C, and that serving changes nothing in the folder."""

from __future__ import annotations

import argparse
import json
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Iterator
from pathlib import Path

import pytest
from shared import Folder, warm

from rig.cli import monitor as cli
from rig.core.exits import EXIT_BAD_INPUT
from rig.monitor.server import STATIC, is_loopback, make_server, page_url
from rig_process import HANG_S


def get(url: str, headers: dict[str, str] | None = None) -> tuple[int, dict[str, str], bytes]:
    request = urllib.request.Request(url, headers=headers or {})
    try:
        with urllib.request.urlopen(request, timeout=HANG_S) as reply:
            return reply.status, dict(reply.headers), reply.read()
    except urllib.error.HTTPError as exc:
        return exc.code, dict(exc.headers), exc.read()


@pytest.fixture
def folder(tmp_path: Path) -> Folder:
    f = Folder(tmp_path / "run")
    warm(f)
    f.pending("01-000", 110.0)
    f.row("01-001", 105.0)
    return f


def serve(folder: Path, token: str | None = None) -> Iterator[str]:
    server = make_server(folder, "127.0.0.1", 0, token)
    thread = threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)
    thread.start()
    try:
        yield page_url(server, None).rstrip("/")
    finally:
        server.shutdown()
        server.server_close()


@pytest.fixture
def base(folder: Folder) -> Iterator[str]:
    yield from serve(folder.path)


def files_of(folder: Path) -> dict[str, tuple[int, int]]:
    return {str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns) for p in folder.rglob("*")}


def test_the_state_is_json_and_increments_from_where_the_viewer_stopped(base, folder):
    status, headers, body = get(base + "/api/state")
    assert status == 200 and headers["Content-Type"] == "application/json"
    first = json.loads(body)
    assert first["phase"] == "measuring" and first["progress"]["done"] == 2
    assert {c["id"] for c in first["changes"] if c["k"] == "p"} == {"01-000", "01-001"}
    folder.pending("01-002", 120.0)
    time.sleep(0.6)                    # the folder is read at most every MIN_READ_INTERVAL_S = 0.5 s
    _, _, body = get(f"{base}/api/state?since={first['next']}&generation={first['generation']}")
    later = json.loads(body)
    assert [c["id"] for c in later["changes"] if c["k"] == "p"] == ["01-002"]
    assert later["progress"]["done"] == 3
    _, _, body = get(f"{base}/api/state?since={later['next']}&generation=another")   # a stale viewer: all again
    assert len(json.loads(body)["changes"]) == later["next"]
    assert get(base + "/api/state?since=x")[0] == 400


def test_the_page_is_three_files_that_ask_nothing_of_any_other_server(base):
    for route, (_, kind) in STATIC.items():
        status, headers, body = get(base + route)
        assert status == 200 and headers["Content-Type"] == kind
        assert "default-src 'self'" in headers["Content-Security-Policy"]
        assert re.search(rb"https?://|(src|href)=\"//|url\(", body, re.I) is None, route
    assert get(base + "/nothing")[0] == 404


def test_serving_changes_nothing_in_the_folder(base, folder):
    before = files_of(folder.path)
    for _ in range(3):
        for route in (*STATIC, "/api/state?since=0"):
            assert get(base + route)[0] == 200
    assert files_of(folder.path) == before


def test_a_host_header_other_than_loopback_is_refused(base):
    port = base.rsplit(":", 1)[1]
    assert get(base + "/", {"Host": f"attacker.example:{port}"})[0] == 403
    assert get(base + "/", {"Host": f"localhost:{port}"})[0] == 200


def test_with_a_token_every_request_needs_it(folder):
    for base in serve(folder.path, token="s3cret"):
        for route in (*STATIC, "/api/state"):
            assert get(base + route)[0] == 403
            assert get(base + route + ("&" if "?" in route else "?") + "token=wrong")[0] == 403
            assert get(base + route + ("&" if "?" in route else "?") + "token=s3cret")[0] == 200


def test_with_a_token_the_page_loads_its_script_and_style_sheet(folder):
    """What a browser does with the printed address (issue 30, item 7): every file the page names, resolved
    against the page's address, is served; the script's own request carries the token from the address."""
    for base in serve(folder.path, token="s3/cr+t"):
        page = base + "/?token=" + urllib.parse.quote("s3/cr+t", safe="")
        status, _, body = get(page)
        assert status == 200
        named = [n for n in re.findall(r'(?:src|href)="([^"]+)"', body.decode()) if not n.startswith("data:")]
        assert len(named) == 2
        for name in named:
            status, headers, _ = get(urllib.parse.urljoin(page, name))
            assert status == 200, name
        script = get(urllib.parse.urljoin(page, named[-1]))[2].decode()
        assert 'q.set("token", token)' in script and 'fetch("api/state?"' in script


def test_only_loopback_addresses_go_without_a_token():
    assert all(is_loopback(h) for h in ("127.0.0.1", "127.0.0.2", "::1", "[::1]", "localhost"))
    assert not any(is_loopback(h) for h in ("0.0.0.0", "192.168.1.5", "::", "lab-pc"))


def run_cli(*argv: str) -> int:
    parser = argparse.ArgumentParser()
    cli.add_subcommand(parser.add_subparsers())
    args = parser.parse_args(["monitor", *argv])
    return args.func(args)


def test_a_port_in_use_is_bad_input_one_message_naming_the_port_and_exit_2(tmp_path, capsys):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert run_cli(str(tmp_path), "--port", str(port)) == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"cannot serve on 127.0.0.1 port {port}" in err
    assert f"another program uses port {port}" in err and "--port" in err


def test_a_port_out_of_range_is_refused_by_the_parser(capsys):
    with pytest.raises(SystemExit) as stop:
        run_cli(".", "--port", "70000")
    assert stop.value.code == EXIT_BAD_INPUT and "not a TCP port" in capsys.readouterr().err


@pytest.mark.parametrize("where, message", [("no/such/run", "neither it nor its parent"),
                                            ("file.txt", "is not a folder")])
def test_a_folder_that_cannot_be_is_one_message_and_exit_2(tmp_path, capsys, where, message):
    (tmp_path / "file.txt").write_text("x")
    assert run_cli(str(tmp_path / where), "--port", "0") == EXIT_BAD_INPUT
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and message in err


def test_another_address_prints_a_token_that_is_required_and_ctrl_c_stops(tmp_path):
    script = ("import sys; from rig.cli.monitor import add_subcommand; import argparse; "
              "p = argparse.ArgumentParser(); add_subcommand(p.add_subparsers()); "
              "a = p.parse_args(sys.argv[1:]); sys.exit(a.func(a))")
    proc = subprocess.Popen([sys.executable, "-c", script, "monitor", str(tmp_path / "later"), "--host", "0.0.0.0",
                             "--port", "0"], stderr=subprocess.PIPE, text=True)
    assert proc.stderr is not None
    try:
        lines = [proc.stderr.readline() for _ in range(3)]
        url = re.search(r"at (http://\S+)", lines[0])
        assert url is not None and "?token=" in url.group(1), lines
        assert "waiting for" in lines[2] and "the run creates it" in lines[2]
        local = url.group(1).replace("0.0.0.0", "127.0.0.1")
        assert get(local.split("?")[0])[0] == 403
        status, _, body = get(local.replace("/?", "/api/state?"))
        assert status == 200 and json.loads(body)["phase"] == "waiting"
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=HANG_S)
    assert proc.returncode == 0 and "stopped" in err and "Traceback" not in err


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_stops_it_even_when_started_with_sigint_ignored(tmp_path, sig):
    """A background job of a script starts with SIGINT ignored, and Python then raises no KeyboardInterrupt:
    `rig monitor` installs its own handlers before it prints its address (CI once hung here for 120 s)."""
    script = ("import sys; from rig.cli.monitor import add_subcommand; import argparse; "
              "p = argparse.ArgumentParser(); add_subcommand(p.add_subparsers()); "
              "a = p.parse_args(sys.argv[1:]); sys.exit(a.func(a))")
    proc = subprocess.Popen([sys.executable, "-c", script, "monitor", str(tmp_path / "later"), "--port", "0"],
                            stderr=subprocess.PIPE, text=True,
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_IGN))
    assert proc.stderr is not None
    try:
        assert "rig monitor:" in proc.stderr.readline()
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=HANG_S)
    finally:
        proc.kill()
    assert proc.returncode == 0 and "stopped" in err
