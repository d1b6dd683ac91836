"""The monitor's connections, bounded: what a hostile or broken client can hold is limited in number and time.

http.server's ThreadingHTTPServer gives each connection a thread at once and waits for its request without a
time limit, so idle sockets lock the monitor out (issue 30, item 11): every one holds a thread and a file
descriptor before any token is checked, and at the open-file limit `accept()` fails while the listening socket
stays readable, which spins the loop at 100 % CPU. Here instead:
- one thread (the one in `serve_forever`) accepts connections and reads each request's head (request line and
  headers) without blocking; a connection costs a socket and a few kB until its head is complete, and none is
  handed to a worker before; a head must arrive within `head_timeout_s` and fit in `max_head_bytes`;
- at most `max_waiting` connections wait for their head: a new one closes the oldest, so that a client that
  sends its request at once (the page, the token holder) always gets in, however many idle sockets are held;
- complete heads go to `workers` threads through a queue of at most `max_queued` (beyond: 503 at once); a
  worker has `send_timeout_s` for the whole answer;
- when `accept()` fails for lack of descriptors (EMFILE, ENFILE, ENOBUFS, ENOMEM) the oldest waiting connections
  are closed to make room, and from then on fewer may wait, leaving FD_MARGIN descriptors for answering (the
  request's socket, the folder's files); with none to close the listening socket rests for `backoff_s` instead
  of spinning;
- a client that goes away mid-answer (BrokenPipeError, ConnectionResetError, a timeout) only ends its
  connection: no traceback.
"""

from __future__ import annotations

import errno
import queue
import selectors
import socket
import sys
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field

#: accept() errors that mean "no descriptor or buffer for one more socket now".
OUT_OF_DESCRIPTORS = frozenset({errno.EMFILE, errno.ENFILE, errno.ENOBUFS, errno.ENOMEM})
#: Answers sent by the accepting thread itself (non-blocking, best effort) when a request cannot be taken.
REFUSALS = {status: f"HTTP/1.0 {status} {reason}\r\nContent-Length: 0\r\nConnection: close\r\n\r\n".encode()
            for status, reason in ((431, "Request Header Fields Too Large"), (503, "Service Unavailable"))}

#: Descriptors kept free for answering once the open-file limit has been met: a worker's socket and the files
#: of the folder it reads, one at a time, for each worker.
FD_MARGIN = 8
#: A connection's handling: (socket, client address, the request's head as received).
Handle = Callable[[socket.socket, tuple, bytes], None]


@dataclass(frozen=True)
class Limits:
    """What one server may hold; the defaults serve a lab's few viewers with room to spare."""

    head_timeout_s: float = 5.0
    send_timeout_s: float = 10.0
    max_head_bytes: int = 16384
    max_waiting: int = 64
    max_queued: int = 32
    workers: int = 4
    backoff_s: float = 0.2


#: What `rig monitor` uses.
DEFAULT_LIMITS = Limits()


@dataclass
class _Waiting:
    sock: socket.socket
    address: tuple
    since: float
    head: bytearray = field(default_factory=bytearray)


class BoundedServer:
    """A TCP server with socketserver's surface (`serve_forever`, `shutdown`, `server_close`, `server_address`)
    whose connections are bounded as the module says; `handle` serves one complete request head."""

    def __init__(self, host: str, port: int, handle: Handle, limits: Limits = DEFAULT_LIMITS):
        self.socket = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET)
        try:
            self.socket.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)     # a restart finds its port free
            self.socket.bind((host.strip("[]"), port))
            self.socket.listen(128)
        except OSError:
            self.socket.close()
            raise
        self.socket.setblocking(False)
        self.server_address = self.socket.getsockname()
        self.handle, self.limits = handle, limits
        self._selector = selectors.DefaultSelector()
        self._waiting: dict[socket.socket, _Waiting] = {}        # insertion order: oldest first
        self._max_waiting = limits.max_waiting                   # lowered at the open-file limit
        self._queue: queue.Queue[tuple[socket.socket, tuple, bytes] | None] = queue.Queue(limits.max_queued)
        self._workers: list[threading.Thread] = []
        self._listening_again_at: float | None = None            # resting after running out of descriptors
        self._stop = threading.Event()
        self._stopped = threading.Event()
        self._stopped.set()

    # -- the accepting thread ------------------------------------------------------------------
    def serve_forever(self, poll_interval: float = 0.5) -> None:
        """Accept and read heads until `shutdown()`; the workers start with it."""
        self._stopped.clear()
        try:
            while len(self._workers) < self.limits.workers:
                worker = threading.Thread(target=self._work, name="rig-monitor-worker", daemon=True)
                worker.start()
                self._workers.append(worker)
            self._selector.register(self.socket, selectors.EVENT_READ)
            while not self._stop.is_set():
                self._step(poll_interval)
        finally:
            self._stopped.set()

    def _step(self, poll_interval: float) -> None:
        now = time.monotonic()
        timeout = poll_interval
        if self._waiting:
            oldest = next(iter(self._waiting.values()))
            timeout = min(timeout, max(oldest.since + self.limits.head_timeout_s - now, 0.0))
        if self._listening_again_at is not None:
            if now >= self._listening_again_at:
                self._listening_again_at = None
                self._selector.register(self.socket, selectors.EVENT_READ)
            else:
                timeout = min(timeout, self._listening_again_at - now)
        for key, _ in self._selector.select(timeout):
            if key.fileobj is self.socket:
                self._accept()
            elif (waiting := self._waiting.get(key.fileobj)) is not None:  # type: ignore[call-overload]
                self._read_head(waiting)                        # (not closed by an accept of this same round)
        deadline = time.monotonic() - self.limits.head_timeout_s
        for waiting in [w for w in self._waiting.values() if w.since < deadline]:
            self._drop(waiting)

    def _accept(self) -> None:
        for _ in range(self.limits.max_waiting):                # then the others get their turn
            try:
                sock, address = self.socket.accept()
            except BlockingIOError:
                return
            except OSError as exc:
                if exc.errno not in OUT_OF_DESCRIPTORS:
                    continue                                    # that client is gone (ECONNABORTED, …)
                if self._waiting:
                    self._max_waiting = max(len(self._waiting) - FD_MARGIN, 1)
                    while len(self._waiting) >= self._max_waiting:
                        self._drop(next(iter(self._waiting.values())))
                    continue
                self._selector.unregister(self.socket)
                self._listening_again_at = time.monotonic() + self.limits.backoff_s
                return
            sock.setblocking(False)
            if len(self._waiting) >= self._max_waiting:
                self._drop(next(iter(self._waiting.values())))
            self._waiting[sock] = _Waiting(sock, address, time.monotonic())
            self._selector.register(sock, selectors.EVENT_READ)

    def _read_head(self, waiting: _Waiting) -> None:
        try:
            data = waiting.sock.recv(self.limits.max_head_bytes + 1 - len(waiting.head))
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:
            self._drop(waiting)
            return
        waiting.head += data
        end = max(waiting.head.find(b"\r\n\r\n"), waiting.head.find(b"\n\n"))
        if end < 0 and len(waiting.head) <= self.limits.max_head_bytes:
            return
        self._selector.unregister(waiting.sock)
        del self._waiting[waiting.sock]
        if end < 0:
            self._refuse(waiting.sock, 431)
            return
        try:
            self._queue.put_nowait((waiting.sock, waiting.address, bytes(waiting.head)))
        except queue.Full:
            self._refuse(waiting.sock, 503)

    def _drop(self, waiting: _Waiting) -> None:
        self._selector.unregister(waiting.sock)
        del self._waiting[waiting.sock]
        waiting.sock.close()

    @staticmethod
    def _refuse(sock: socket.socket, status: int) -> None:
        try:
            sock.send(REFUSALS[status])
        except OSError:
            pass                                                # best effort: the client may be gone or full
        sock.close()

    # -- the workers -----------------------------------------------------------------------------
    def _work(self) -> None:
        while (item := self._queue.get()) is not None:
            sock, address, head = item
            try:
                sock.setblocking(True)
                sock.settimeout(self.limits.send_timeout_s)
                self.handle(sock, address, head)
            except (ConnectionError, TimeoutError):
                pass                                            # the client went away or stopped reading
            except Exception:                                   # a bug: said, and the worker serves on
                print(f"rig monitor: error answering {address[0]}:", file=sys.stderr)
                traceback.print_exc()
            finally:
                sock.close()

    # -- stopping --------------------------------------------------------------------------------
    def shutdown(self) -> None:
        """Stop `serve_forever` (from another thread) and wait until it has returned."""
        self._stop.set()
        self._stopped.wait()

    def server_close(self) -> None:
        """Close the listening socket and every connection not yet answered; the workers end."""
        for waiting in list(self._waiting.values()):
            self._drop(waiting)
        self._selector.close()
        self.socket.close()
        for _ in self._workers:
            try:
                self._queue.put_nowait(None)
            except queue.Full:
                break                                           # daemon threads: they end with the process
