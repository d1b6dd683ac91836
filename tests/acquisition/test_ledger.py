"""The ledger on its own (rig.acquisition.ledger): points kept and waiting for E⊥, the checkpoints a tripped
suspender rewinds to, and what a rewind takes back."""

from dataclasses import replace

from shared import CONSTANTS, measurement

from rig.acquisition.ledger import Ledger, Mark
from rig.physics.illuminance import IlluminanceEstimate

BEFORE = IlluminanceEstimate(1000.0, 1.0, 0.0, 5, 0.0)
AFTER = IlluminanceEstimate(1010.0, 1.0, 0.0, 5, 10.0)


class Writer:
    """What the ledger writes: events and appended rows."""

    def __init__(self) -> None:
        self.events: list[tuple[str, dict]] = []
        self.rows: list[dict] = []

    def event(self, kind: str, **fields) -> None:
        self.events.append((kind, fields))

    event_synced_behind = event

    def append_rows(self, rows) -> None:
        self.rows.extend(rows)


class Eta:
    def __init__(self) -> None:
        self.left: set[str] = set()

    def done(self, point_id: str) -> None:
        self.left.discard(point_id)

    def undone(self, point_ids) -> None:
        self.left.update(point_ids)


def ledger(interpolate: bool = True, done_rows=()) -> Ledger:
    return Ledger(Writer(), done_rows, CONSTANTS, interpolate, Eta(), lambda: 42.0)


def measure(ledger: Ledger, *ids: str) -> None:
    """Points go ahead and are kept, a second of rig time apart."""
    for k, pid in enumerate(ids):
        m = measurement(rig_time_s=1.0 + k)
        ledger.started()
        ledger.keep(replace(m, point=replace(m.point, point_id=pid)), BEFORE)


def discarded(ledger: Ledger) -> list[tuple[list[str], str]]:
    return [(f["point_ids"], f["reason"]) for kind, f in ledger.writer.events if kind == "points_discarded"]


def test_a_lamp_trip_takes_back_the_points_since_its_last_passing_check():
    book = ledger(done_rows=[{"point_id": "old"}])
    measure(book, "a", "b")
    book.mark(Mark.LAMP_CHECKED)                 # the check vouches for a and b, measured before it
    measure(book, "c", "d")
    assert (book.since(Mark.LAMP_CHECKED), book.since(Mark.READING), book.measured) == (2, 4, 5)
    assert [p.point_id for p in book.rewind(Mark.LAMP_CHECKED, "lamp")] == ["c", "d"]
    assert [m.point.point_id for m in book.pending] == ["a", "b"] and book.measured == 3
    assert discarded(book) == [(["c", "d"], "lamp")] and book.eta.left == {"c", "d"}
    assert book.writer.events[-1][1]["rig_time_s"] == 42.0


def test_an_illuminance_jump_takes_back_every_point_since_the_reading():
    book = ledger()
    measure(book, "a", "b")
    book.mark(Mark.LAMP_CHECKED)
    measure(book, "c")
    assert [p.point_id for p in book.rewind(Mark.READING, "illuminance jump")] == ["a", "b", "c"]
    assert book.pending == [] and book.measured == 0 and book.since(Mark.LAMP_CHECKED) == 0


def test_a_rewind_with_no_mark_of_its_own_still_takes_back_what_no_lamp_check_vouched_for():
    """A pause for a silent device, or the exit, makes the waiting rows final without a check: the points since the
    lamp's last passing check go first, and only once."""
    book = ledger()
    measure(book, "a")
    book.mark(Mark.LAMP_CHECKED)
    measure(book, "b", "c")
    assert [p.point_id for p in book.rewind(None, "lamp not checked since")] == ["b", "c"]
    assert book.rewind(None, "lamp not checked since") == [] and discarded(book) == [(["b", "c"],
                                                                                      "lamp not checked since")]
    book.write_pending(BEFORE, None)
    assert [r["point_id"] for r in book.writer.rows] == ["a"] and book.since(Mark.READING) == 0


def test_a_point_started_and_not_kept_still_counts_since_the_check():
    """Its device went silent mid-point: the rewind takes back as many points as were started since the check, so
    at worst one point measured before it is measured again (as with the lamp checked before every point)."""
    book = ledger()
    measure(book, "a", "b")
    book.mark(Mark.LAMP_CHECKED)
    book.started()                               # c: polled, then its camera stopped answering
    assert [p.point_id for p in book.rewind(None, "lamp not checked since")] == ["b"]
    assert book.since(Mark.LAMP_CHECKED) == 0


def test_rows_become_final_at_the_next_reading_interpolated_between_the_two():
    book = ledger()
    measure(book, "a", "b")
    assert [kind for kind, _ in book.writer.events] == ["point_pending"] * 2 and book.writer.rows == []
    book.write_pending(BEFORE, AFTER)
    rows = book.writer.rows
    assert [r["point_id"] for r in rows] == ["a", "b"] and all(r["illuminance_interpolated"] == 1 for r in rows)
    assert 1000.0 < rows[0]["illuminance_normal_lx"] < rows[1]["illuminance_normal_lx"] < 1010.0
    assert book.pending == [] and book.rows == rows and book.rewind(Mark.READING, "illuminance jump") == []


def test_without_interpolation_a_row_is_final_at_once_and_nothing_waits():
    book = ledger(interpolate=False)
    measure(book, "a")
    assert [r["point_id"] for r in book.writer.rows] == ["a"] and book.writer.events == []
    assert book.rewind(Mark.LAMP_CHECKED, "lamp") == [] and book.measured == 1
