"""The progress line: a rig-time ETA that is right early (issue 9, defect 8), and a bar that fits the terminal."""

from __future__ import annotations

import io
import re

import pytest

from rig.acquisition.engine import Runner
from rig.acquisition.progress import ProgressBar
from rig.config.campaign import parse_campaign
from rig.config.rigfile import RigConfig
from rig.core.values import Progress
from rig.data.dataset_writer import DatasetWriter
from rig.planning.plan import build_plan
from rig.simulators.rig import SimulatedRig


def test_rig_time_eta_at_ten_percent_is_within_30_percent_of_the_remaining_rig_time(tmp_path):
    """The warm-up (over 5 min here, a few s per point) must not be extrapolated over the points left."""
    campaign = parse_campaign({
        "name": "eta",
        "sample": {"id": "S", "simulated_brdf": {"model": "lambert", "params": {"kd": 0.5}}},
        "incidence": [{"phi": 0, "theta": [0, 30, 60]}],
        "viewing": [{"centred_on": "normal", "theta": [10, 30, 50], "phi": [0, 60, 120, 180, 240, 300]}],
    })
    rig = RigConfig()
    plan = build_plan(campaign, rig)
    seen: list[Progress] = []
    writer = DatasetWriter(tmp_path / "ds", {})
    with SimulatedRig(rig, "lambert", {"kd": 0.5}) as sim:
        assert Runner(campaign, plan, sim.devices, writer, rig, progress=seen.append).run() == "complete"
    writer.close()
    total = len(plan.points)
    assert total >= 40
    at_tenth = next(p for p in seen if p.done >= 0.1 * total)
    last_point = max(p.rig_time_s for p in seen if p.done == total)
    remaining = last_point - at_tenth.rig_time_s
    assert at_tenth.rig_time_s > remaining / 5                  # the warm-up weighs: naive extrapolation fails
    assert at_tenth.eta_rig_s == pytest.approx(remaining, rel=0.3)
    assert seen[-1].eta_rig_s == pytest.approx(0.0, abs=1e-9)


class Terminal(io.StringIO):
    """A fake terminal: isatty, no file descriptor (so the width comes from `columns` or COLUMNS)."""

    def isatty(self) -> bool:
        return True


def records(total: int = 200) -> list[Progress]:
    long_message = "PAUSED (illuminance) 1200 s: E⊥ still changing: 10012.3 → 10387.9 lx " * 3
    return [Progress(done, total, 300.0 + 4.0 * done, long_message if done % 7 == 0 else f"θi={done}°",
                     eta_rig_s=4.0 * (total - done)) for done in range(total + 1)]


def drawn_lines(text: str) -> list[str]:
    return [line for line in re.split(r"[\r\n]", text) if line]


@pytest.mark.parametrize("columns", [20, 40, 80, 159])
def test_bar_never_writes_a_line_wider_than_the_terminal(columns):
    term = Terminal()
    bar = ProgressBar(term, min_interval_s=0.0, columns=columns)
    for p in records():
        bar(p)
    lines = drawn_lines(term.getvalue())
    assert len(lines) == 201
    assert max(len(line) for line in lines) <= columns - 1     # the last column would wrap on many terminals
    assert term.getvalue().endswith("\n")                      # the finished bar is left on its own line


def test_bar_follows_the_columns_variable_when_it_has_no_terminal_to_ask(monkeypatch):
    monkeypatch.setenv("COLUMNS", "50")
    term = Terminal()
    bar = ProgressBar(term, min_interval_s=0.0)
    for p in records(20):
        bar(p)
    assert max(len(line) for line in drawn_lines(term.getvalue())) <= 49


def test_bar_shows_the_runners_rig_time_eta_and_a_wall_time_eta_once_points_are_done():
    term = Terminal()
    bar = ProgressBar(term, min_interval_s=0.0, columns=160)
    bar(Progress(0, 100, 320.0, "lamp warm-up", eta_rig_s=3000.0))
    assert "ETA 0:50:00 rig" in term.getvalue() and "wall" not in term.getvalue()
    bar(Progress(1, 100, 330.0, "", eta_rig_s=2970.0))
    bar(Progress(2, 100, 360.0, "", eta_rig_s=2940.0))
    last = drawn_lines(term.getvalue())[-1]
    assert re.search(r"ETA \d+:\d\d:\d\d wall, 0:49:00 rig", last)


def test_plain_lines_every_ten_percent_when_not_a_terminal():
    out = io.StringIO()
    bar = ProgressBar(out)
    for p in records(100):
        bar(p)
    lines = out.getvalue().splitlines()
    assert len(lines) == 11 and lines[-1].startswith("[") and "100/100" in lines[-1]
