"""`rig plot` and `rig report` on a dataset without u (an ALTA import without `#VS`, like the shipped CEA tape):
the figures are drawn without error bars and the report says u is not stated (issue 30, item 3)."""

from pathlib import Path

import numpy as np
import pytest

from rig.cli.main import main
from rig.data.dataset_reader import load

#: Every this many data lines of the tape are kept: a few hundred points, all three incidences.
EVERY = 25


@pytest.fixture(scope="module")
def tape(cea_dir, tmp_path_factory) -> Path:
    """The gray tape (no #VS: no u) thinned to every 25th point, imported by `rig import`."""
    folder = tmp_path_factory.mktemp("tape")
    lines = (cea_dir / "retro-gray-tape.alta").read_text().splitlines()
    head = [line for line in lines if line.startswith("#")]
    data = [line for line in lines if line and not line.startswith("#")]
    (folder / "gray.alta").write_text("\n".join(head + data[::EVERY]) + "\n")
    assert main(["import", str(folder / "gray.alta"), "--out", str(folder / "ds")]) == 0
    return folder


def test_the_thinned_tape_has_no_u(tape):
    ds = load(tape / "ds")
    assert len(np.unique(ds["series"])) == 3
    assert np.all(np.isnan(ds["u_brdf_per_sr"]))


def test_plot_draws_a_dataset_without_u(tape, capsys):
    assert main(["plot", str(tape / "ds"), "--out", str(tape / "figures")]) == 0, capsys.readouterr().err
    assert len(list((tape / "figures").glob("plane_*.png"))) == 3


def test_report_says_u_not_stated(tape, capsys):
    out = tape / "report.html"
    assert main(["report", str(tape / "ds"), "--out", str(out)]) == 0, capsys.readouterr().err
    assert "u not stated" in out.read_text()
