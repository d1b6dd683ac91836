"""The line-instrument base (rig.drivers.line_instrument) on its own: each way a setting is confirmed (an
acknowledgement line, the error queue, not at all), a refused setting's message, a setting and its
confirmation retried together, and the events held until a sink is attached. The drivers' own byte exchanges
from the manuals are in test_p9710.py, test_fw102c.py and test_delta_sm.py."""

import pytest

from rig.core.errors import DeviceError
from rig.drivers.line_instrument import Acknowledgement, ErrorQueue, LineInstrument, Query, Setting
from rig.drivers.retry import RetryPolicy

LEVEL = Setting("LEVEL {}")
ERRORS = Query("ERR?", lambda reply: (int(reply.partition(",")[0]), reply))
QUEUE = ErrorQueue(ERRORS, size=3)
EMPTY = (b"ERR?\n", b"0,none\n")


class Unconfirmed(LineInstrument):
    """An instrument whose settings are not confirmed (the base's default)."""

    def __init__(self, open_port, clock):
        super().__init__("loop://", name="box", clock=clock, timeout_s=0.2, open_port=open_port,
                         retry=RetryPolicy(attempts=2, backoff_s=0.01))


class Acknowledging(Unconfirmed):
    confirmation = Acknowledgement("the bare line feed that acknowledges it")

    def check_refusal(self, line: str, reply: str) -> None:
        if reply.startswith("?"):
            raise DeviceError(self.name, f"{line!r} refused: {reply}")


class Queued(Unconfirmed):
    confirmation = QUEUE


class Holding(Queued):
    """Reports an event while it connects, before anyone can attach a sink."""

    holds_events = True

    def __init__(self, open_port, clock):
        super().__init__(open_port, clock)
        self.events("connected", device=self.name)


def test_unconfirmed_setting_is_only_written(expected_protocol, clock):
    with expected_protocol([(b"LEVEL 3\n", None)]) as replay:      # a read would fail the replay
        Unconfirmed(replay.open_port, clock).put(LEVEL, 3)


def test_acknowledgement_line_confirms_a_setting(expected_protocol, clock):
    with expected_protocol([(b"LEVEL 3\n", b"\n")]) as replay:
        Acknowledging(replay.open_port, clock).put(LEVEL, 3)


def test_another_reply_than_the_acknowledgement_is_transient_and_named(expected_protocol, clock):
    with expected_protocol([(b"LEVEL 3\n", b"12\n")]) as replay:
        with pytest.raises(DeviceError) as err:
            Acknowledging(replay.open_port, clock).put(LEVEL, 3)
    assert str(err.value) == "box: 'LEVEL 3' answered '12' instead of the bare line feed that acknowledges it"
    assert err.value.transient


def test_an_acknowledgement_refused_by_the_instrument_is_persistent(expected_protocol, clock):
    with expected_protocol([(b"LEVEL 3\n", b"?2\n")]) as replay:
        with pytest.raises(DeviceError) as err:
            Acknowledging(replay.open_port, clock).put(LEVEL, 3)
    assert str(err.value) == "box: 'LEVEL 3' refused: ?2" and not err.value.transient


def test_acknowledgement_waits_as_long_as_asked(expected_protocol, clock):
    with expected_protocol([(b"LEVEL 3\n", b"\n")]) as replay:
        Acknowledging(replay.open_port, clock).put(LEVEL, 3, timeout_s=7.0)
    assert replay.read_timeouts == [7.0]


def test_an_empty_error_queue_confirms_a_setting(expected_protocol, clock):
    with expected_protocol([(b"LEVEL 3\n", None), EMPTY]) as replay:
        Queued(replay.open_port, clock).put(LEVEL, 3)


def test_error_queue_entries_refuse_the_setting_with_their_text(expected_protocol, clock):
    entries = [(b"ERR?\n", b"-221,Settings conflict\n"), (b"ERR?\n", b"-222,Data out of range\n"), EMPTY]
    with expected_protocol([(b"LEVEL 3\n", None), *entries]) as replay:
        with pytest.raises(DeviceError) as err:
            Queued(replay.open_port, clock).put(LEVEL, 3)
    assert str(err.value) == "box: 'LEVEL 3' refused: -221,Settings conflict; -222,Data out of range"
    assert not err.value.transient


def test_the_error_queue_is_read_at_most_its_size(expected_protocol, clock):
    full = [(b"ERR?\n", f"-{n},stale\n".encode()) for n in (1, 2, 3)]
    with expected_protocol([(b"LEVEL 3\n", None), *full]) as replay:
        with pytest.raises(DeviceError, match="refused: -1,stale; -2,stale; -3,stale$"):
            Queued(replay.open_port, clock).put(LEVEL, 3)


def test_tolerated_objections_are_an_event_not_a_refusal(expected_protocol, clock, events):
    with expected_protocol([(b"LEVEL 0\n", None), (b"ERR?\n", b"-221,Settings conflict\n"), EMPTY]) as replay:
        box = Queued(replay.open_port, clock)
        box.events = lambda kind, **fields: events.append((kind, fields))
        box.put(LEVEL, 0, tolerate_errors=True)
    assert events == [("device_errors", {"device": "box", "what": "LEVEL 0", "errors": ["-221,Settings conflict"]})]


def test_apply_retries_the_setting_with_its_confirmation(expected_protocol, clock, events):
    """A confirmation lost (no reply to the queue read) costs a reconnect and the setting sent again."""
    with expected_protocol([(b"LEVEL 3\n", None), (b"ERR?\n", b""), (b"LEVEL 3\n", None), EMPTY]) as replay:
        box = Queued(replay.open_port, clock)
        box.events = lambda kind, **fields: events.append((kind, fields))
        box.apply(LEVEL, 3)
    assert [kind for kind, _ in events] == ["retry", "reconnect"]
    assert events[0][1]["what"] == "LEVEL 3" and replay.opens == 2


def test_events_of_the_connection_are_held_for_the_first_sink(expected_protocol, clock):
    with expected_protocol([]) as replay:
        box = Holding(replay.open_port, clock)
        first: list[tuple[str, dict]] = []
        second: list[tuple[str, dict]] = []
        box.events = lambda kind, **fields: first.append((kind, fields))
        box.events("later", device="box")
        box.events = lambda kind, **fields: second.append((kind, fields))
    assert first == [("connected", {"device": "box"}), ("later", {"device": "box"})] and second == []


def test_without_holding_events_before_a_sink_go_nowhere(expected_protocol, clock):
    with expected_protocol([]) as replay:
        box = Queued(replay.open_port, clock)
        box.events("unheard", device="box")
        heard: list[tuple[str, dict]] = []
        box.events = lambda kind, **fields: heard.append((kind, fields))
    assert heard == []
