"""The monitor's HTTP server: the page, its script and style, and `/api/state` (stdlib http.server's request
parsing, over the bounded connections of rig.monitor.front).

Read-only by construction: the only routes are GETs of three package files and of the
follower's snapshot (rig.monitor.folder); nothing a request says reaches the folder.

Access: on a loopback address anyone on this machine may look, and the Host header must name
that address (a web page elsewhere cannot reach the monitor through DNS rebinding). On any
other address a random token, printed at start, is required as `?token=` on every request;
it is compared in constant time. The page served with a token names its script and style sheet
with the token, so that a browser given the printed address loads them too.

First paint: the page comes with the folder's state as of the request (a JSON data block, which the
CSP does not execute, and the phase and counts in the text), so that it shows the run as soon as it
loads, before any poll (a headless screenshot taken at load showed "CONNECTING…").
"""

from __future__ import annotations

import hmac
import html
import io
import ipaddress
import json
import secrets
import socket
import threading
import time
from http import HTTPStatus
from http.server import BaseHTTPRequestHandler
from importlib import resources
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs, quote, urlsplit

from rig.monitor.folder import FolderFollower
from rig.monitor.front import DEFAULT_LIMITS, BoundedServer, Limits

#: The page's files (package data, rig/monitor/static/): route → (file, content type).
STATIC = {"/": ("monitor.html", "text/html; charset=utf-8"),
          "/monitor.js": ("monitor.js", "text/javascript; charset=utf-8"),
          "/monitor.css": ("monitor.css", "text/css; charset=utf-8")}
#: Shortest wall time between two reads of the folder, however many viewers poll: the run's disk
#: sees at most this rate of reads from the monitor.
MIN_READ_INTERVAL_S = 0.5
#: No request of the page may leave this server (the lab PC may be offline; nothing is fetched elsewhere).
CSP = ("default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data:; connect-src 'self'; "
       "object-src 'none'; base-uri 'none'; form-action 'none'; frame-ancestors 'none'")
LOOPBACK_NAMES = ("localhost",)


def is_loopback(host: str) -> bool:
    """Whether `host` (an address or `localhost`) is this machine's loopback."""
    if host in LOOPBACK_NAMES:
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def new_token() -> str:
    return secrets.token_urlsafe(18)


def static_file(route: str, token: str | None) -> bytes:
    """A page file; the page itself with the token added to its script's and style sheet's addresses."""
    body = resources.files("rig.monitor").joinpath("static", STATIC[route][0]).read_bytes()
    if route == "/" and token is not None:
        for other in STATIC:
            if other != "/":
                name = other.lstrip("/")
                body = body.replace(f'"{name}"'.encode(), f'"{name}?token={quote(token, safe="")}"'.encode())
    return body


def first_paint(page: bytes, state: bytes) -> bytes:
    """The page with `state` (an /api/state answer) in it: as a data block for the script, and its phase and
    counts as text."""
    snapshot = json.loads(state)
    progress = snapshot["progress"]
    fills = {b'<span class="phase" id="phase">connecting\xe2\x80\xa6</span>': ("phase", snapshot["phase"]),
             b'<span id="done">0</span>': ("done", str(progress["done"])),
             b'<span id="to-measure">?</span>': ("to-measure", "?" if progress["to_measure"] is None
                                                  else str(progress["to_measure"]))}
    for old, (name, value) in fills.items():
        attributes = ' class="phase"' if name == "phase" else ""
        page = page.replace(old, f'<span{attributes} id="{name}">{html.escape(value)}</span>'.encode())
    block = b'<script id="initial-state" type="application/json">' + state.replace(b"<", b"\\u003c") + b"</script>"
    return page.replace(b"</body>", block + b"\n</body>")


class Monitor:
    """The follower shared by every request, read at most every MIN_READ_INTERVAL_S."""

    def __init__(self, folder: Path):
        self.follower = FolderFollower(folder)
        self._lock = threading.Lock()
        self._read_at = -float("inf")

    def snapshot(self, since: int, generation: str | None) -> bytes:
        with self._lock:
            now = time.monotonic()
            if now - self._read_at >= MIN_READ_INTERVAL_S:
                self.follower.update()
                self._read_at = now
            if generation != self.follower.generation:
                since = 0                       # a new viewer, or the follower started over
            return json.dumps(self.follower.snapshot(since), allow_nan=False).encode()


class Handler(BaseHTTPRequestHandler):
    """One request, whose head rig.monitor.front has read already (HTTP/1.0: one request per connection)."""

    server_version = "rig-monitor"

    def __init__(self, sock: socket.socket, address: tuple, server: Any, *, head: bytes, monitor: Monitor,
                 token: str | None, quiet: bool):
        self.head, self.monitor, self.token, self.quiet = head, monitor, token, quiet
        super().__init__(sock, address, server)

    def setup(self) -> None:
        super().setup()
        self.rfile.close()
        self.rfile = io.BytesIO(self.head)

    def log_message(self, format: str, *args) -> None:
        if not self.quiet:
            super().log_message(format, *args)

    def _refuse(self, status: HTTPStatus, why: str) -> None:
        self._send(status, why.encode(), "text/plain; charset=utf-8")

    def _send(self, status: HTTPStatus, body: bytes, kind: str) -> None:
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(body)))
        self.send_header("Cache-Control", "no-store")
        self.send_header("Content-Security-Policy", CSP)
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Referrer-Policy", "no-referrer")
        self.end_headers()
        self.wfile.write(body)

    def _allowed(self, query: dict[str, list[str]]) -> str | None:
        """Why the request is refused, or None."""
        if self.token is not None:
            given = query.get("token", [""])[0]
            return None if hmac.compare_digest(given.encode(), self.token.encode()) else \
                "a token is required: open the address `rig monitor` printed at start (…?token=…)"
        host = (self.headers.get("Host") or "").rsplit(":", 1)[0]
        return None if is_loopback(host) else f"Host {host!r} is not this machine's loopback address"

    def do_GET(self) -> None:
        url = urlsplit(self.path)
        query = parse_qs(url.query)
        refusal = self._allowed(query)
        if refusal is not None:
            self._refuse(HTTPStatus.FORBIDDEN, refusal)
        elif url.path in STATIC:
            body = static_file(url.path, self.token)
            if url.path == "/":
                body = first_paint(body, self.monitor.snapshot(0, None))
            self._send(HTTPStatus.OK, body, STATIC[url.path][1])
        elif url.path == "/api/state":
            try:
                since = int(query.get("since", ["0"])[0])
            except ValueError:
                self._refuse(HTTPStatus.BAD_REQUEST, "since: a whole number")
                return
            body = self.monitor.snapshot(since, query.get("generation", [None])[0])
            self._send(HTTPStatus.OK, body, "application/json")
        else:
            self._refuse(HTTPStatus.NOT_FOUND, "not found")


def make_server(folder: Path, host: str, port: int, token: str | None, *, quiet: bool = True,
                limits: Limits = DEFAULT_LIMITS) -> BoundedServer:
    """A server (not yet serving) for `folder` on host:port (port 0: a free one); OSError if it cannot bind."""
    monitor = Monitor(folder)

    def handle(sock: socket.socket, address: tuple, head: bytes) -> None:
        Handler(sock, address, server, head=head, monitor=monitor, token=token, quiet=quiet)
    server = BoundedServer(host, port, handle, limits)
    return server


def page_url(server: BoundedServer, token: str | None) -> str:
    address, port = server.server_address[:2]
    host = str(address)
    host = f"[{host}]" if ":" in host else host
    return f"http://{host}:{port}/" + (f"?token={token}" if token else "")
