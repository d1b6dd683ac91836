"""A seeded fuzz and soak of `rig monitor` (issue 30, "done when"): random and hostile events.jsonl and brdf.csv
content, and bounded hostile connections, while the state keeps answering valid JSON.

The content is rig's own lines (tests/monitor/test_folder.py writes them as rig.data.dataset_writer does) mixed with
those lines mutated byte by byte, cut, or with a field swapped for a hostile value (NaN, Infinity, 1e999, an
integer beyond 4300 digits, a list for an id, 128 kB, deep nesting, NUL and invalid UTF-8), and random bytes.
Every line the fuzzer writes ends with a newline, so each rig line it writes must be followed whatever
surrounds it. Seeds, counts and sizes are fixed: the same bytes every run, a few seconds in all.
"""

from __future__ import annotations

import json
import socket
import threading
import urllib.error
import urllib.request
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
from shared import Folder, row, utc, warm

from rig.data.dataset_format import BRDF_COLUMNS, csv_line
from rig.monitor import server as server_module
from rig.monitor.front import Limits
from rig.monitor.server import make_server, page_url

SEED = 20261127
ROUNDS, LINES_PER_ROUND = 80, 12
HANG_GUARD_S = 10.0
HOSTILE_VALUES: list[Any] = [float("nan"), float("inf"), -float("inf"), 1e308, -1e308, 10 ** 300, [], {}, ["x"],
                             {"a": {"b": None}}, None, True, "", "x" * 140_000, "\u2028\u0000\udfff"]
HOSTILE_TEXT = ["NaN", "Infinity", "-Infinity", "1e999", "7" * 5000, "[" * 3000 + "]" * 3000,
                "[" * 200 + "]" * 200, '{"event": ' * 100, "\x00", "\ufeff{}", '"unterminated', "{}", "null", "1"]


def hostile_json(value: Any) -> str:
    """A JSON-ish text of `value`; NaN and Infinity as Python writes them (rig never does)."""
    return json.dumps(value, allow_nan=True)


class Fuzzer:
    """Writes one round of lines into a Folder; remembers the point ids of the untouched rig lines."""

    def __init__(self, folder: Folder, rng: np.random.Generator):
        self.f, self.rng, self.n = folder, rng, 0
        self.sound_ids: set[str] = set()

    def _mutate(self, line: bytes) -> bytes:
        data = bytearray(line)
        for _ in range(int(self.rng.integers(1, 6))):
            kind = self.rng.integers(4)
            at = int(self.rng.integers(len(data) + 1))
            if kind == 0 and data:
                data[min(at, len(data) - 1)] = int(self.rng.integers(256))
            elif kind == 1:
                data[at:at] = bytes(self.rng.integers(0, 256, int(self.rng.integers(1, 20)), dtype=np.uint8))
            elif kind == 2:
                del data[at:at + int(self.rng.integers(1, 30))]
            else:
                data = data[:at]
        return bytes(data).replace(b"\n", b" ")

    def _event(self) -> tuple[bytes, str | None]:
        self.n += 1
        pid = f"{1 + self.n // 50:02d}-{self.n:03d}"
        rig_s = 100.0 + self.n
        kinds = [("point_pending", {"row": row(pid, rig_s)}),
                 ("illuminance", {"illuminance_normal_lx": 4990.0, "u_lx": 4.0, "readings": 5}),
                 ("suspended", {"device": "lamp", "reason": "lamp current 0.000 A"}),
                 ("resumed", {"device": "lamp", "waited_s": 3.0}),
                 ("points_discarded", {"point_ids": [pid], "reason": "lamp"}),
                 ("adaptive_batch", {"points": [pid]})]
        kind, fields = kinds[int(self.rng.integers(len(kinds)))]
        record = {"time_utc": utc(rig_s), "event": kind, "rig_time_s": rig_s, **fields}
        return json.dumps(record).encode(), pid if kind == "point_pending" else None

    def _hostile_event(self) -> bytes:
        record: dict[str, Any] = json.loads(self._event()[0])
        keys = [*record, "row", "point_ids"]
        key = keys[int(self.rng.integers(len(keys)))]
        if self.rng.random() < 0.5:
            record[key] = HOSTILE_VALUES[int(self.rng.integers(len(HOSTILE_VALUES)))]
            return hostile_json(record).encode("utf-8", "surrogatepass")
        text = hostile_json({**record, key: 0})
        return text.replace(f'"{key}": 0', f'"{key}": {HOSTILE_TEXT[int(self.rng.integers(len(HOSTILE_TEXT)))]}',
                            1).encode()

    def _row(self) -> bytes:
        self.n += 1
        return csv_line(row(f"{1 + self.n // 50:02d}-{self.n:03d}", 100.0 + self.n)[c] for c in BRDF_COLUMNS).encode()

    def _hostile_row(self) -> bytes:
        values = row(f"99-{self.n:03d}", 100.0)
        cells = [str(values[c]) for c in BRDF_COLUMNS]
        cells[int(self.rng.integers(len(cells)))] = ["nan", "inf", "-inf", "1e999", "7" * 5000, "x" * 140_000,
                                                     '"', "\x00", ""][int(self.rng.integers(9))]
        return ",".join(cells).encode("utf-8", "surrogatepass")

    def round(self) -> None:
        events, rows = bytearray(), bytearray()
        for _ in range(LINES_PER_ROUND):
            pick = self.rng.random()
            if pick < 0.35:
                line, pid = self._event()
                if pid is not None:
                    self.sound_ids.add(pid)
            elif pick < 0.5:
                line = self._mutate(self._event()[0])
            elif pick < 0.65:
                line = self._hostile_event()
            elif pick < 0.7:
                line = bytes(self.rng.integers(0, 256, int(self.rng.integers(0, 200)), dtype=np.uint8))
            else:
                maker: Callable[[], bytes] = [self._row, lambda: self._mutate(self._row()),
                                              self._hostile_row][int(self.rng.integers(3))]
                rows += maker().rstrip(b"\n").replace(b"\n", b" ") + b"\n"
                continue
            events += line.replace(b"\n", b" ") + b"\n"
        with (self.f.path / "events.jsonl").open("ab") as fh:
            fh.write(events)
        with (self.f.path / "brdf.csv").open("ab") as fh:
            fh.write(rows)


def strict(body: bytes | dict) -> dict:
    """JSON as a browser's JSON.parse takes it: no NaN or Infinity."""
    text = json.dumps(body, allow_nan=False) if isinstance(body, dict) else body.decode()
    return json.loads(text, parse_constant=lambda name: pytest.fail(f"{name} in the state"))


def test_random_and_hostile_lines_never_stop_the_state(tmp_path):
    f = Folder(tmp_path / "run")
    warm(f)
    fuzz = Fuzzer(f, np.random.default_rng(SEED))
    seen: set[str] = set()
    since, generation, bad = 0, None, 0
    for _ in range(ROUNDS):
        fuzz.round()
        s = strict(f.look(since))
        assert generation in (None, s["generation"])          # appended to, never taken for another folder
        generation, since = s["generation"], s["next"]
        seen |= {c["id"] for c in s["changes"] if c["k"] == "p"}
        assert s["bad_lines"] >= bad and len(s["warnings"]) <= 10
        bad = s["bad_lines"]
    assert fuzz.sound_ids <= seen                               # every rig line was followed
    assert bad > ROUNDS                                         # and the fuzz did reach the skipping


def hostile_client(port: int, rng: np.random.Generator) -> None:
    """One hostile connection: junk, a partial head, a huge one, wrong tokens, odd `since`, or a reset."""
    sock = socket.create_connection(("127.0.0.1", port), timeout=HANG_GUARD_S)
    try:
        kind = int(rng.integers(7))
        if kind == 0:
            sock.sendall(bytes(rng.integers(0, 256, int(rng.integers(1, 3000)), dtype=np.uint8)))
        elif kind == 1:
            sock.sendall(b"GET /api/state?token=")                        # and nothing more
        elif kind == 2:
            sock.sendall(b"GET / HTTP/1.1\r\nX: " + b"a" * 40_000)
        elif kind == 3:
            sock.sendall(b"GET /api/state?since=" + b"9" * 5000 + b"&token=" + FUZZ_TOKEN.encode() + b" HTTP/1.0\r\n"
                         b"\r\n")
        elif kind == 4:
            sock.sendall(b"GET /../../etc/passwd?token=nope HTTP/1.0\r\n\r\n")
        elif kind == 5:
            sock.sendall(b"POST /api/state?token=" + FUZZ_TOKEN.encode() + b" HTTP/1.0\r\nContent-Length: 9\r\n\r\n")
        else:
            sock.sendall(f"GET /api/state?token={FUZZ_TOKEN} HTTP/1.0\r\n\r\n".encode())
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
    finally:
        sock.close()


FUZZ_TOKEN = "fuzz-token"


def test_the_server_answers_through_hostile_content_and_connections(tmp_path, monkeypatch, capfd):
    monkeypatch.setattr(server_module, "MIN_READ_INTERVAL_S", 0.0)      # every request reads the folder
    f = Folder(tmp_path / "run")
    warm(f)
    rng = np.random.default_rng(SEED + 1)
    fuzz = Fuzzer(f, rng)
    server = make_server(f.path, "127.0.0.1", 0, FUZZ_TOKEN, limits=Limits(head_timeout_s=0.5, max_waiting=16))
    threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True).start()
    port = server.server_address[1]
    held = []
    try:
        url = page_url(server, FUZZ_TOKEN).replace("/?", "/api/state?")
        for i in range(ROUNDS // 3):
            fuzz.round()
            for _ in range(4):
                hostile_client(port, rng)
            held.append(socket.create_connection(("127.0.0.1", port), timeout=HANG_GUARD_S))   # idle, kept
            with urllib.request.urlopen(url, timeout=HANG_GUARD_S) as reply:
                assert reply.status == 200
                state = strict(reply.read())
            assert state["phase"] in ("measuring", "paused") and state["bad_lines"] >= i
        with pytest.raises(urllib.error.HTTPError) as refused:
            urllib.request.urlopen(url.replace(FUZZ_TOKEN, "wrong"), timeout=HANG_GUARD_S)
        assert refused.value.code == 403
    finally:
        for s in held:
            s.close()
        server.shutdown()
        server.server_close()
    assert "Traceback" not in capfd.readouterr().err
