"""`rig fit` on data without uncertainties (defect 7): an imported ALTA file without #VS carries
u_brdf_per_sr = 0; the fit is unweighted by default then, with a one-line notice, `--weighted`
refuses it (exit 2, naming the column), and a dataset where only some rows have u is refused
unless the user chooses `--unweighted`."""

import csv
import json

import numpy as np
import pytest

from rig.analysis.fit import choose_weighting
from rig.cli.main import main
from rig.data.alta import write_alta

KD = 0.6


def lambert_alta(path, ci=None):
    """A small isotropic Lambertian measurement (f = kd/π) as an ALTA file; `ci` the ± column or None."""
    th_i, th_o, ph_o = np.meshgrid(np.radians([0, 30, 60]), np.radians([10, 30, 50, 70]), np.radians([0, 90, 180]),
                                   indexing="ij")
    x = np.c_[th_i.ravel(), np.zeros(th_i.size), th_o.ravel(), ph_o.ravel()]
    f = np.full(len(x), KD / np.pi) * (1 + 0.01 * np.sin(np.arange(len(x))))
    return write_alta(path, x, f, param_in="SPHERICAL_TL_PL_TV_PV", param_out="INV_STERADIAN", ci=ci)


@pytest.fixture
def imported(tmp_path):
    """`rig import` of the file without uncertainties (#VS 0): every row has u = 0."""
    out = tmp_path / "no-u"
    assert main(["import", str(lambert_alta(tmp_path / "no-u.alta")), "--out", str(out)]) == 0
    return out


def test_no_uncertainties_fit_unweighted_by_default_with_one_line_notice(imported, tmp_path, capsys):
    capsys.readouterr()
    out = tmp_path / "fit.json"
    assert main(["fit", str(imported), "--model", "lambert", "--json", str(out)]) == 0
    captured = capsys.readouterr()
    notice = [line for line in captured.err.splitlines() if "unweighted" in line]
    assert len(notice) == 1 and "u_brdf_per_sr" in notice[0] and str(imported) in notice[0]
    assert "weighting none" in captured.out
    result = json.loads(out.read_text())
    assert result["diagnostics"]["weighting"] == "none"
    assert result["params"]["kd"] == pytest.approx(KD, rel=0.02)


def test_weighted_refused_without_uncertainties_and_nothing_written(imported, tmp_path, capsys):
    capsys.readouterr()
    out = tmp_path / "fit.json"
    assert main(["fit", str(imported), "--model", "lambert", "--weighted", "--json", str(out)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("rig: error:") and len(err.splitlines()) == 1
    assert "--weighted" in err and "u_brdf_per_sr" in err and "36 of 36 rows" in err
    assert not out.exists()


def test_unweighted_still_works_and_says_nothing_extra(imported, capsys):
    capsys.readouterr()
    assert main(["fit", str(imported), "--model", "lambert", "--unweighted"]) == 0
    captured = capsys.readouterr()
    assert "weighting none" in captured.out and "unweighted" not in captured.err


def test_weighted_and_unweighted_exclude_each_other(imported, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["fit", str(imported), "--model", "lambert", "--weighted", "--unweighted"])
    assert exc.value.code == 2


def test_uncertainties_on_every_row_weight_the_fit_by_default(tmp_path, capsys):
    out = tmp_path / "with-u"
    src = lambert_alta(tmp_path / "u.alta", ci=np.full(36, 0.002))
    assert main(["import", str(src), "--out", str(out)]) == 0
    capsys.readouterr()
    assert main(["fit", str(out), "--model", "lambert"]) == 0
    captured = capsys.readouterr()
    assert "weighting uncertainty" in captured.out and "χ²/dof" in captured.out
    assert "unweighted" not in captured.err


def test_some_rows_without_uncertainty_refused_unless_unweighted(tmp_path, capsys):
    out = tmp_path / "mixed"
    assert main(["import", str(lambert_alta(tmp_path / "u.alta", ci=np.full(36, 0.002))), "--out", str(out)]) == 0
    brdf = out / "brdf.csv"
    with open(brdf, newline="", encoding="utf-8") as fh:
        reader = csv.DictReader(fh)
        header, rows = reader.fieldnames, list(reader)
    for row in rows[5:8]:                      # three rows lost their u (say, merged from another source)
        row["u_brdf_per_sr"] = "0.0"
    with open(brdf, "w", newline="", encoding="utf-8") as fh:
        writer = csv.DictWriter(fh, header, lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    capsys.readouterr()
    assert main(["fit", str(out), "--model", "lambert"]) == 2
    err = capsys.readouterr().err
    assert "3 of 36 rows" in err and "u_brdf_per_sr" in err and rows[5]["point_id"] in err and "--unweighted" in err
    assert main(["fit", str(out), "--model", "lambert", "--weighted"]) == 2
    assert "3 of 36 rows" in capsys.readouterr().err
    assert main(["fit", str(out), "--model", "lambert", "--unweighted"]) == 0


@pytest.mark.parametrize("u, requested, want", [
    ([0.1, 0.2], None, ("uncertainty", False)),
    ([0.0, np.nan], None, ("none", True)),
    ([0.0, 0.0], "none", ("none", False)),
    ([0.1, 0.2], "none", ("none", False)),
    ([0.1, 0.2], "uncertainty", ("uncertainty", False)),
    ([], None, ("uncertainty", False)),
])
def test_choose_weighting(u, requested, want):
    weighting, notice = choose_weighting(np.array(u, float), [f"p{k}" for k in range(len(u))], requested)
    assert (weighting, notice is not None) == want


@pytest.mark.parametrize("u, requested, match", [
    ([0.1, -0.2], None, "1 of 2 rows .* e.g. point p1"),
    ([0.0, np.inf], "uncertainty", "--weighted needs u_brdf_per_sr on every row; 2 of 2"),
    ([0.1], "chi2", "weighting 'chi2'"),
])
def test_choose_weighting_refusals(u, requested, match):
    with pytest.raises(ValueError, match=match):
        choose_weighting(np.array(u, float), [f"p{k}" for k in range(len(u))], requested)
