"""A public SM15K client's queries against the lamp supply `rig sim serve` serves, as a lab's script would send them.

The client is github keklikyusuf/DeltaElektronika `SM15K.py` (v0.0.7): one TCP connection per message to port
8462, the message with its LF, one `recv(1024)` for a query's reply, then close. Its code is not used here: the
small client below does what its `Communication.sendMessage`/`sendReceiveMessage` document, and the messages are
its own, transliterated, in the order of its `Test…Subsystem` methods. Each reply is checked against the format
the manual ("Ethernet & Sequencer Programming SM15K", rev. July 2021) gives for it.

Two of its queries are written with the manual's notation for an optional node, `SYSTem:RSD[:STAtus]?` and
`SYSTem:FROntpanel[:STAtus]?`, brackets included: not the syntax (§4.5: `[ ]` may be used or skipped), so the
supply answers nothing and queues an error, while both forms the manual means are answered.
"""

from __future__ import annotations

import re
import socket
from collections.abc import Iterator

import pytest

from rig.config.rigfile import simulated_rig
from rig.simulators.delta_sm_peer import DeltaSMPeer
from rig.simulators.served import PAPER_RM1, ServedRig

#: s; the client waits 10 s for a reply, which no test can afford for each of the two unanswered queries.
TIMEOUT_S = 0.3

NR2 = r"-?\d+\.\d{4}"                      # setpoints and V/I measurements: 4 digits (§5.2.1, §5.3.2-3)
MAXIMUM = r"-?\d+"                         # maxima: integers (§5.2.1)
SCIENTIFIC = r"-?\d\.\d{15}e[+-]\d\d"      # step sizes and instrument totals (§5.2.12, §5.3.5)
NUMBER = r"-?\d+(\.\d+)?"
BOOL = r"[01]"
ENTRY = r"-?\d+,.+"                        # error and warning entries, `0,None` when empty (§5.6.7-8)

#: The client's queries, in the order of its test methods, and the reply format the manual gives.
QUERIES = [
    ("*IDN?", r"DELTA ELEKTRONIKA BV,[^,]+,[^,]+,[^,]+,[^,]*"),
    ("*PUD?", r"[A-Za-z0-9 _-]{0,72}"),
    ("SOURce:VOLtage:MAXimum?", MAXIMUM), ("SOURce:CURrent:MAXimum?", MAXIMUM),
    ("SOURce:CURrent:NEGative:MAXimum?", MAXIMUM), ("SOURce:POWer:MAXimum?", MAXIMUM),
    ("SOURce:POWer:NEGative:MAXimum?", MAXIMUM),
    ("SOURce:VOLtage?", NR2), ("SOURce:CURrent?", NR2), ("SOURce:CURrent:NEGative?", NR2), ("SOURce:POWer?", NR2),
    ("SOURce:POWer:NEGative?", NR2),
    ("SOURce:VOLtage:STEpsize?", SCIENTIFIC), ("SOURce:CURrent:STEpsize?", SCIENTIFIC),
    ("SOURce:POWer:STEpsize?", SCIENTIFIC),
    ("MEASure:VOLtage?", NR2), ("MEASure:CURrent?", NR2), ("MEASure:POWer?", r"-?\d+\.\d{2}"),
    *[(f"MEASure:INStrument {kind},{what}", form) for kind, extreme in (("AH", "I"), ("WH", "P"))
      for what, form in (("STATE?", "OFF|ON|SUSPEND|RESUME"), ("TIMEHR?", r"\d+\.\d{3}"), ("TIMESEC?", r"\d+\.\d"),
                         ("POS,TOTAL?", SCIENTIFIC), ("NEG,TOTAL?", SCIENTIFIC), (f"POS,{extreme}MIN?", NUMBER),
                         (f"POS,{extreme}MAX?", NUMBER), (f"NEG,{extreme}MIN?", NUMBER),
                         (f"NEG,{extreme}MAX?", NUMBER))],
    ("MEASure:TEMperature?", NUMBER),
    ("SYSTem:LIMits:VOLtage?", NUMBER), ("SYSTem:LIMits:CURrent?", NUMBER),
    ("SYSTem:LIMits:CURrent:NEGative?", NUMBER), ("SYSTem:LIMits:POWer?", NUMBER),
    ("SYSTem:LIMits:POWer:NEGative?", NUMBER),
    ("SYSTem:FROntpanel:CONtrols?", BOOL),
    ("SYSTem:TIMe?", r"UNKNOWN|\d{1,2}:\d\d:\d\d"), ("SYSTem:DATe?", r"UNKNOWN|\d{4}-\d{1,2}-\d{1,2}"),
    ("SYSTem:ERRor?", ENTRY), ("SYSTem:WARning?", ENTRY),
    ("SYSTem:COMmunicate:WATchdog SET?", MAXIMUM), ("SYSTem:COMmunicate:WATchdog?", MAXIMUM),
    ("OUTPut?", BOOL),
]
#: The client's two queries written in the manual's notation, and the forms the manual means.
BRACKETED = ["SYSTem:RSD[:STAtus]?", "SYSTem:FROntpanel[:STAtus]?"]
MEANT = ["SYSTem:RSD?", "SYSTem:RSD:STAtus?", "SYSTem:FROntpanel?", "SYSTem:FROntpanel:STAtus?"]


class SocketPerMessage:
    """What SM15K.py's `Communication` does: connect, send the message, (for a query) one recv(1024), close."""

    def __init__(self, url: str):
        host, port = url.removeprefix("socket://").rsplit(":", 1)
        self.address = (host, int(port))

    def _connect(self) -> socket.socket:
        sock = socket.create_connection(self.address, timeout=TIMEOUT_S)
        return sock

    def send(self, message: str) -> None:
        with self._connect() as sock:
            sock.sendall(f"{message}\n".encode())

    def ask(self, message: str) -> str | None:
        """The reply without its LF, or None if none came within TIMEOUT_S."""
        with self._connect() as sock:
            sock.sendall(f"{message}\n".encode())
            try:
                data = sock.recv(1024)
            except TimeoutError:
                return None
        assert data.endswith(b"\n"), data
        return data.decode("utf-8").rstrip("\n")


@pytest.fixture(scope="module")
def served() -> Iterator[tuple[DeltaSMPeer, SocketPerMessage]]:
    rig = ServedRig(simulated_rig(), *PAPER_RM1)
    rig.start()
    try:
        yield rig.lamp, SocketPerMessage(rig.lamp.url or "")
    finally:
        rig.stop()


def test_every_query_of_the_public_client_gets_a_reply_in_the_manuals_format(served):
    peer, client = served
    replies = {query: client.ask(query) for query, _ in QUERIES}
    wrong = {q: replies[q] for q, form in QUERIES if replies[q] is None or not re.fullmatch(form, replies[q] or "")}
    assert wrong == {}
    assert len(QUERIES) + len(BRACKETED) == 52
    assert client.ask("SYSTem:ERRor?") == "0,None"


def test_the_bracketed_notation_is_refused_and_the_forms_it_stands_for_answered(served):
    peer, client = served
    assert [client.ask(q) for q in BRACKETED] == [None, None]
    assert [client.ask("SYSTem:ERRor?") for _ in BRACKETED] == ["-113,Undefined header"] * 2
    assert [client.ask(q) for q in MEANT] == ["0", "0", "0", "0"]


def test_the_clients_settings_take_effect_as_the_manual_says(served):
    """The settings of the client's test methods (values for its own 500 V supply where the served one is smaller:
    those beyond this supply's maxima are refused, one error each), then read back."""
    peer, client = served
    for message in ("*CLS", "SYSTem:REMote:CV Remote", "SYSTem:REMote:CC Remote", "SYSTem:REMote:CP Remote",
                    "SOURce:VOLtage 5", "SOURce:CURrent 5", "SOURce:CURrent:NEGative -5", "SOURce:POWer 100",
                    "SOURce:POWer:NEGative -100", "MEASure:INStrument AH,STATE,ON", "SYSTem:RSD OFF",
                    "SYSTem:LIMits:VOLtage 50,ON", "SYSTem:FROntpanel ON", "SYSTem:FROntpanel:CONtrols ON",
                    "SYSTem:TIMe 9,10,0", "SYSTem:DATe 2021,9,8", "SYSTem:COMmunicate:WATchdog SET,500",
                    "SYSTem:COMmunicate:WATchdog STOP", "OUTPut 1", "OUTPut 0"):
        client.send(message)
    assert [client.ask(q) for q in ("SOURce:VOLtage?", "SOURce:CURrent:NEGative?", "SOURce:POWer?",
                                    "MEASure:INStrument AH,STATE?", "SYSTem:FROntpanel?", "SYSTem:DATe?")] == \
        ["5.0000", "-5.0000", "100.0000", "ON", "1", "2021-9-8"]
    assert re.fullmatch(r"9:10:\d\d", client.ask("SYSTem:TIMe?") or "")
    assert client.ask("STATus:REGister:B?") == "7"                          # CV, CC and CP programmed remotely
    assert [client.ask("SYSTem:ERRor?") for _ in range(2)] == ["-222,Data out of range", "0,None"]  # 50 V > 15 V
    client.send("*RST")
    assert [client.ask(q) for q in ("SOURce:VOLtage?", "SYSTem:FROntpanel?", "OUTPut?")] == ["0.0000", "0", "0"]
