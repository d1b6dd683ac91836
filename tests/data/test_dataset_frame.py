"""A clean simulated run's rows and flags, empty not-applicable cells of an imported dataset, and the
pandas view of a dataset folder (`load_frame`, `Dataset.to_frame`)."""

import sys
from pathlib import Path

import numpy as np
import pytest

from rig.data import importer
from rig.data.alta import write_alta
from rig.data.dataset_format import BRDF_COLUMNS, DatasetError
from rig.data.dataset_reader import load, load_frame

pd = pytest.importorskip("pandas", reason="pandas is a test dependency (optional extra `pandas`)")


@pytest.fixture
def imported(tmp_path) -> Path:
    """An ALTA file without #VS (no uncertainty) imported as a dataset."""
    x = np.radians([[10.0, 0.0, 20.0, 180.0], [40.0, 0.0, 30.0, 0.0]])
    src = write_alta(tmp_path / "s.alta", x, [0.3, 0.5], param_in="SPHERICAL_TL_PL_TV_PV", param_out="INV_STERADIAN")
    return importer.import_alta(src, tmp_path / "imported")


def test_clean_simulated_run_has_empty_flags_and_says_e_perp_was_interpolated(e2e_run):
    """`rig run` of tests/campaigns/e2e-reduced.yaml on the simulated rig (illuminance.correction: interpolate)."""
    ds = load(e2e_run)
    assert len(ds) == 103
    assert all(f == () for f in ds.flags)          # no routine-correction flag on clean rows
    np.testing.assert_array_equal(ds["illuminance_interpolated"], 1.0)
    assert np.all(ds["u_rel_drift"] >= 0) and np.all(np.isfinite(ds["u_brdf_per_sr"]))


def test_frame_of_a_run_has_typed_columns(e2e_run):
    frame = load_frame(e2e_run)
    assert list(frame.columns) == list(BRDF_COLUMNS) and len(frame) == 103
    assert frame["flags"].dtype == "string" and (frame["flags"] == "").all()
    assert frame["point_id"].dtype == "string" and frame["point_id"].is_unique
    assert frame["series"].dtype == "Int64" and frame["n_frames"].dtype == "Int64"
    assert frame["illuminance_interpolated"].dtype == "boolean" and frame["illuminance_interpolated"].all()
    assert frame["brdf_per_sr"].dtype == np.float64 and str(frame["time_utc"].dt.tz) == "UTC"
    assert all(isinstance(e, tuple) and len(e) >= 1 for e in frame["exposures_s"])
    ds = load(e2e_run)
    np.testing.assert_array_equal(frame["brdf_per_sr"].to_numpy(), ds["brdf_per_sr"])
    assert frame.attrs["units"]["brdf_per_sr"] == "1/sr" and frame.attrs["manifest"]["status"] == "complete"


def test_imported_dataset_leaves_not_applicable_cells_empty(imported):
    lines = (imported / "brdf.csv").read_text().splitlines()
    header, first = lines[0].split(","), lines[1].split(",")
    cell = dict(zip(header, first))
    for column in ("u_brdf_per_sr", "u_luminance_cd_m2", "stage_vertical_deg", "arm_azimuth_deg", "rig_time_s",
                   "saturated_fraction", "n_frames", "u_rel_noise", "u_rel_drift", "illuminance_interpolated"):
        assert cell[column] == "", column
    assert float(cell["brdf_per_sr"]) == pytest.approx(0.3, rel=1e-15)
    frame = load_frame(imported)
    assert frame["u_brdf_per_sr"].isna().all() and frame["stage_vertical_deg"].isna().all()
    assert frame["n_frames"].isna().all() and frame["illuminance_interpolated"].isna().all()
    assert frame["series"].tolist() == [0, 1] and list(frame["flags"]) == ["imported;no_uncertainty"] * 2


def test_an_empty_cell_is_refused_where_a_value_is_required(imported):
    path = imported / "brdf.csv"
    lines = path.read_text().splitlines(keepends=True)
    header = lines[0].rstrip("\n").split(",")
    cells = lines[1].split(",")
    cells[header.index("brdf_per_sr")] = ""
    path.write_text(lines[0] + ",".join(cells))
    with pytest.raises(DatasetError, match=r"brdf.csv:2: column brdf_per_sr: '' is not a finite number"):
        load(imported)


def test_without_pandas_the_error_says_what_to_install(imported, monkeypatch):
    monkeypatch.setitem(sys.modules, "pandas", None)          # makes `import pandas` fail
    with pytest.raises(ImportError, match=r"need pandas: pip install 'rig\[pandas\]'"):
        load_frame(imported)
