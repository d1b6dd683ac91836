"""ALTA vertical segments (#VS) read and written as ALTA's loader reads them, the coverage factor k,
#KEY lines after the data; hand-made files in tests/data/alta_files/ (each says what ALTA does with it)."""

from pathlib import Path

import numpy as np
import pytest

from rig.cli.main import main
from rig.data import importer
from rig.data.alta import AltaError, read_alta, to_rig, write_alta
from rig.data.dataset_reader import load
from rig.data.export import ExportError, export, export_alta

FILES = Path(__file__).parent / "alta_files"
X = np.radians([[10.0, 0.0, 20.0, 180.0], [40.0, 0.0, 30.0, 0.0], [40.0, 0.0, 10.0, 90.0]])


def test_vs2_columns_are_distances_below_and_above_y():
    data = read_alta(FILES / "vs2_distances.alta")
    p = to_rig(data)
    # the segments ALTA builds: [y − d₋, y + d₊]
    lower, upper = data.y[:, 0] - data.ci[:, 0], data.y[:, 0] + data.ci[:, 1]
    np.testing.assert_allclose(lower, [0.29, 0.9, 0.2], rtol=1e-12)
    np.testing.assert_allclose(upper, [0.31, 1.3, 0.25], rtol=1e-12)
    np.testing.assert_allclose(p.u_brdf, [0.01, 0.2, 0.025], rtol=1e-12)     # 0.30 0.01 0.01 is not u = 0
    np.testing.assert_allclose(p.brdf, [0.30, 1.0, 0.2], rtol=1e-12)
    assert any("k = 1" in n for n in p.notes)


def test_vs1_column_is_the_half_width_taken_as_k1_without_a_rig_comment():
    data = read_alta(FILES / "vs1_half_width.alta")
    assert data.coverage_k is None
    np.testing.assert_allclose(to_rig(data).u_brdf, [0.05, 0.2], rtol=1e-12)


def test_a_rig_coverage_comment_divides_the_half_width_by_k():
    data = read_alta(FILES / "vs1_rig_k2.alta")
    assert data.coverage_k == pytest.approx(2.0, rel=1e-15)
    p = to_rig(data)
    np.testing.assert_allclose(p.u_brdf, [0.05, 0.2], rtol=1e-12)
    assert any("k = 2 from the file's rig coverage comment" in n for n in p.notes)


def test_key_lines_after_the_data_are_skipped_with_a_note():
    data = read_alta(FILES / "key_after_data.alta")
    assert len(data) == 2 and data.vs == 1 and "SAMPLE" not in data.header
    np.testing.assert_allclose(data.ci[:, 0], [0.05, 0.2], rtol=1e-12)
    assert [n.split(":")[0] for n in data.notes] == ["line 9", "line 10"]
    assert any("'#VS 2' after the data skipped" in n for n in to_rig(data).notes)


@pytest.mark.parametrize("vs", [1, 2])
def test_write_read_round_trip_keeps_alta_semantics(tmp_path, vs):
    u = np.array([0.01, 0.02, 0.05])
    ci = u if vs == 1 else np.stack([0.5 * u, 1.5 * u], axis=1)          # half-width (d₋ + d₊)/2 = u
    path = write_alta(tmp_path / "w.alta", X, [0.3, 0.5, 0.7], param_in="SPHERICAL_TL_PL_TV_PV",
                      param_out="INV_STERADIAN", ci=ci * 3.0, coverage_k=3.0)
    text = path.read_text()
    assert f"#VS {vs}\n" in text and "# rig coverage_k=3.0:" in text
    np.testing.assert_allclose(to_rig(read_alta(path)).u_brdf, u, rtol=1e-12)


@pytest.mark.parametrize("text, line, words", [
    ("#VS 2\n0 0 0 0 1 0.1 0.1\n0 0 0 0 1 -0.1 0.1\n", 5, "segment distances below/above y -0.1 0.1: one is "
                                                         "negative"),
    ("#VS 1\n0 0 0 0 1 -0.1\n", 4, "uncertainty ±-0.1 is negative"),
])
def test_negative_segments_are_refused(tmp_path, text, line, words):
    path = tmp_path / "n.alta"
    path.write_text("#DIM 4 1\n#PARAM_IN SPHERICAL_TL_PL_TV_PV\n" + text)
    with pytest.raises(AltaError, match=f"{path}:{line}: {words}"):
        to_rig(read_alta(path), assume_param_out="INV_STERADIAN")


def test_a_bad_coverage_comment_is_refused(tmp_path):
    path = tmp_path / "k.alta"
    path.write_text("# rig coverage_k=0: nonsense\n#DIM 4 1\n#VS 1\n0 0 0 0 1 0.1\n")
    with pytest.raises(AltaError, match="does not give a positive k"):
        read_alta(path)


@pytest.fixture
def measured(tmp_path) -> Path:
    """A dataset with u on every row (imported from a #VS 1 file with u = 0.01, 0.02, 0.05)."""
    src = write_alta(tmp_path / "src.alta", X, [0.3, 0.5, 0.7], param_in="SPHERICAL_TL_PL_TV_PV",
                     param_out="INV_STERADIAN", ci=[0.01, 0.02, 0.05])
    return importer.import_alta(src, tmp_path / "measured")


@pytest.mark.parametrize("k", [1.0, 2.0])
def test_export_writes_k_times_u_and_import_reads_u_back(tmp_path, measured, k):
    out, = export_alta(load(measured), tmp_path / f"k{k}.alta", coverage_k=k)
    data = read_alta(out)
    assert data.vs == 1 and data.coverage_k == pytest.approx(k, rel=1e-15)
    np.testing.assert_allclose(data.ci[:, 0], k * np.array([0.01, 0.02, 0.05]), rtol=1e-12)
    again = load(importer.import_alta(out, tmp_path / f"again{k}"))
    np.testing.assert_allclose(again["u_brdf_per_sr"], [0.01, 0.02, 0.05], rtol=1e-12)


def test_export_default_is_k1_stated_in_the_file(tmp_path, measured):
    out, = export(load(measured), "alta", tmp_path / "default.alta")
    assert "# rig coverage_k=1.0:" in out.read_text() and read_alta(out).coverage_k == pytest.approx(1.0)


def test_export_without_uncertainty_is_vs0(tmp_path):
    src = write_alta(tmp_path / "src.alta", X, [0.3, 0.5, 0.7], param_in="SPHERICAL_TL_PL_TV_PV",
                     param_out="INV_STERADIAN")
    ds = load(importer.import_alta(src, tmp_path / "no_u"))
    assert np.all(np.isnan(ds["u_brdf_per_sr"]))
    out, = export(ds, "alta", tmp_path / "no_u.alta")
    data = read_alta(out)
    assert data.vs == 0 and data.ci.shape == (3, 0) and data.coverage_k is None
    assert "#VS 0\n" in out.read_text() and any("3 of 3 rows have no usable u" in c for c in data.comments)


def test_one_row_without_u_makes_the_file_vs0(tmp_path, measured):
    ds = load(measured)
    ds.columns["u_brdf_per_sr"][1] = np.nan
    out, = export(ds, "alta", tmp_path / "mixed.alta")
    data = read_alta(out)
    assert data.vs == 0 and any("1 of 3 rows have no usable u" in c for c in data.comments)


@pytest.mark.parametrize("k", [0.0, -1.0, float("nan")])
def test_export_refuses_a_bad_k(tmp_path, measured, k):
    with pytest.raises(ExportError, match="coverage factor k must be a positive number"):
        export_alta(load(measured), tmp_path / "bad.alta", coverage_k=k)


def test_rig_import_reports_skipped_key_lines_and_the_k_it_assumed(tmp_path, capsys):
    assert main(["import", str(FILES / "key_after_data.alta"), "--out", str(tmp_path / "ds")]) == 0
    err = capsys.readouterr().err
    assert "line 9: '#VS 2' after the data skipped" in err and "taken as k = 1" in err
    assert load(tmp_path / "ds").manifest["provenance"]["vs"] == 1
