"""`rig monitor DIR [--port N] [--host H]`: a live, read-only web view of a dataset folder (docs/monitor.md)."""

from __future__ import annotations

import argparse
import errno
import signal
import sys
from pathlib import Path

from rig.core.exits import EXIT_OK, fail
from rig.monitor.server import is_loopback, make_server, new_token, page_url

DEFAULT_PORT = 8765


def cmd_monitor(args: argparse.Namespace) -> int:
    """Serve until Ctrl+C. A folder that cannot be (a missing parent, a file) or a port that cannot be
    had (in use, an address not this machine's) is bad input: one message and exit 2; a folder not made
    yet is waited for."""
    folder = Path(args.dir)
    if folder.exists() and not folder.is_dir():
        return fail(f"{folder} is not a folder (give a dataset folder)")
    if not folder.exists() and not folder.parent.is_dir():
        return fail(f"{folder}: neither it nor its parent folder {folder.parent} exists")
    token = None if is_loopback(args.host) else new_token()
    try:
        server = make_server(folder, args.host, args.port, token, quiet=not args.verbose)
    except OSError as exc:
        in_use = exc.errno == errno.EADDRINUSE
        return fail(f"cannot serve on {args.host} port {args.port}: {exc.strerror or exc}"
                    + (f" (another program uses port {args.port}: choose another with --port)" if in_use else ""))
    # Ctrl+C and SIGTERM stop it, even where the shell started it with SIGINT ignored (a background job of a
    # script inherits that, and Python then raises no KeyboardInterrupt): as `rig run`, it installs its own.
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, signal.default_int_handler)
    try:
        print(f"rig monitor: {folder} at {page_url(server, token)} (read-only; Ctrl+C stops it)", file=sys.stderr,
              flush=True)
        if token:
            print(f"rig monitor: access token {token} (required on {args.host}: give the whole address above)",
                  file=sys.stderr, flush=True)
        if not folder.exists():
            print(f"rig monitor: waiting for {folder} to appear (the run creates it)", file=sys.stderr, flush=True)
        server.serve_forever(poll_interval=0.2)
    except KeyboardInterrupt:
        print("\nrig monitor: stopped", file=sys.stderr)
    finally:
        server.server_close()
    return EXIT_OK


def _port(text: str) -> int:
    """A TCP port number, 0 to 65535 (argparse says so with exit 2 otherwise)."""
    try:
        port = int(text)
    except ValueError:
        port = -1
    if not 0 <= port <= 65535:
        raise argparse.ArgumentTypeError(f"{text!r} is not a TCP port (0 to 65535)")
    return port


def add_subcommand(subparsers: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register `rig monitor`."""
    p = subparsers.add_parser("monitor", help="a live web page of a dataset folder while `rig run` writes it "
                                              "(or after): progress, state, plots, events; read-only")
    p.add_argument("dir", metavar="DIR", help="dataset folder (it may not exist yet: the run creates it)")
    p.add_argument("--port", type=_port, default=DEFAULT_PORT, help=f"TCP port (default {DEFAULT_PORT}; 0: any free)")
    p.add_argument("--host", default="127.0.0.1",
                   help="address to listen on (default 127.0.0.1, this machine only); any other address "
                        "requires the access token printed at start")
    p.add_argument("--verbose", action="store_true", help="log every request on stderr")
    p.set_defaults(func=cmd_monitor)
