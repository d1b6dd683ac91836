"""`rig import`: the real CEA retroreflective tapes (ALTA files) and small synthetic files."""

import argparse
import csv
import hashlib

import numpy as np
import pytest

from rig.cli import import_alta
from rig.data import importer
from rig.data.alta import write_alta
from rig.data.dataset_reader import load
from rig.physics.geometry import angle_between, mirror_direction

#: The vendored CEA tapes (tests/data/cea-retro, the `cea_dir` fixture) by short name.
TAPES = {"yellow": "retro-3M-yellow.alta", "gray": "retro-gray-tape.alta"}


@pytest.fixture(scope="module")
def imported(tmp_path_factory, cea_dir):
    root = tmp_path_factory.mktemp("cea")
    return {name: load(importer.import_alta(cea_dir / file, root / name)) for name, file in TAPES.items()}


@pytest.mark.parametrize("name, rows, sample", [("yellow", 7397, "3M Yellow"), ("gray", 7405, "Gray Tape")])
def test_counts_and_angle_ranges(imported, name, rows, sample):
    ds = imported[name]
    m = ds.manifest
    assert m["status"] == "complete" and m["sample"]["id"] == sample
    assert m["counts"] == {"planned": rows, "measured": rows - 86, "skipped": 86} and len(ds) == rows - 86
    # the 86 views at θV = 90° (on the horizon) cannot be converted
    assert len(ds.skipped) == 86 and {s["reason"] for s in ds.skipped} == {"below_horizon"}
    assert np.allclose([float(s["theta_o_deg"]) for s in ds.skipped], 90.0)
    for s, theta_i in enumerate((15.0, 30.0, 60.0)):
        rows_s = ds["series"] == s
        assert np.allclose(ds["theta_i_deg"][rows_s], theta_i)
    np.testing.assert_allclose(ds["phi_i_deg"], 0.0, rtol=0, atol=1e-12)
    assert ds["theta_o_deg"].min() == pytest.approx(0.0, abs=1e-12) and ds["theta_o_deg"].max() == pytest.approx(87.0)
    assert np.all((ds["phi_o_deg"] >= 0) & (ds["phi_o_deg"] < 360))
    assert np.all(np.isfinite(ds["brdf_per_sr"])) and np.all(ds["brdf_per_sr"] > 0)


def test_yellow_tape_retroreflects_on_the_dphi_zero_side(imported):
    """The convention check: the broad retro lobe lies around ωo = ωi, the narrow top-film peak at the mirror."""
    ds = imported["yellow"]
    wi, wo = ds.directions()
    f = ds["brdf_per_sr"]
    near_retro = np.degrees(angle_between(wi, wo)) < 5.0
    near_mirror = np.degrees(angle_between(mirror_direction(wi), wo)) < 5.0
    retro_side = np.sum(wo[:, :2] * wi[:, :2], axis=1) >= 0          # θV·cos Δφ ≥ 0
    for s in range(3):
        rows = ds["series"] == s
        assert np.median(f[rows & near_retro]) > 4 * np.median(f[rows & near_mirror])
        peak = np.argmax(np.where(rows & retro_side, f, -np.inf))
        assert np.degrees(angle_between(wi[peak], wo[peak])) <= 1.0 + 1e-6
        assert f[peak] > 10.0


def test_values_are_divided_by_cos_theta_v(imported):
    """First data row of the yellow file: θL = 15°, view at θV = 87°, Δφ = 180°, f·cos θV = 0.00362877."""
    ds = imported["yellow"]
    k = ds.point_id.index("00-L11")
    assert ds["theta_o_deg"][k] == pytest.approx(87.0) and ds["phi_o_deg"][k] == pytest.approx(180.0)
    assert ds["brdf_per_sr"][k] == pytest.approx(0.00362877 / np.cos(np.radians(87.0)))
    assert ds["luminance_cd_m2"][k] == pytest.approx(ds["brdf_per_sr"][k] * np.cos(np.radians(15.0)))
    assert ds["illuminance_normal_lx"][k] == 1.0


def test_provenance_in_the_manifest(imported, cea_dir):
    for name, file in TAPES.items():
        path = cea_dir / file
        m = imported[name].manifest
        prov = m["provenance"]
        assert m["rig"]["simulated"] is False
        assert prov["source_file"] == str(path.resolve())
        assert prov["source_sha256"] == hashlib.sha256(path.read_bytes()).hexdigest()
        assert (prov["header"]["PARAM_IN"] == "ISOTROPIC_TL_TV_PROJ_DPHI"
                and prov["param_in"] == prov["header"]["PARAM_IN"])
        assert prov["param_out_used"] == "INV_STERADIAN_COSINE_FACTOR"
        assert prov["conversion"] and prov["conventions"]["point_id"]
    assert imported["yellow"].manifest["provenance"]["param_out"] == "INV_STERADIAN_COSINE_FACTOR"
    gray = imported["gray"].manifest["provenance"]
    assert gray["param_out"] is None and any("assumed" in n for n in gray["conversion"])


def test_rows_are_flagged_and_carry_no_uncertainty(imported):
    ds = imported["gray"]
    assert all(f == ("imported", "no_uncertainty") for f in ds.flags)
    # not applicable: empty cells (NaN), never 0, so that a 1/u² weight cannot divide by zero
    for column in ("u_brdf_per_sr", "u_luminance_cd_m2", "stage_vertical_deg", "arm_polar_deg", "rig_time_s",
                   "u_rel_noise", "illuminance_interpolated"):
        assert np.all(np.isnan(ds[column])), column
    assert ds.point_id[0].startswith("00-L") and len(set(ds.point_id)) == len(ds)


def test_uncertainty_from_vs_and_spherical_angles(tmp_path):
    x = np.radians([[40.0, 0.0, 40.0, 0.0], [40.0, 0.0, 20.0, 180.0], [0.0, 30.0, 10.0, 200.0]])
    src = write_alta(tmp_path / "s.alta", x, [2.0, 0.5, 0.3], param_in="SPHERICAL_TL_PL_TV_PV",
                     param_out="INV_STERADIAN", ci=[0.1, 0.02, 0.01])
    ds = load(importer.import_alta(src, tmp_path / "ds", sample_id="S1"))
    assert ds.manifest["sample"]["id"] == "S1" and len(ds) == 3
    assert np.allclose(ds["theta_o_deg"], [40, 20, 10]) and np.allclose(ds["phi_o_deg"], [0, 180, 200])
    assert np.array_equal(ds["u_brdf_per_sr"], [0.1, 0.02, 0.01])
    assert list(ds["series"]) == [0, 0, 1] and all(f == ("imported",) for f in ds.flags)


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="rig")
    import_alta.add_subcommand(parser.add_subparsers(dest="command", required=True))
    return parser


def test_cli_import(tmp_path, capsys):
    src = write_alta(tmp_path / "s.alta", np.radians([[10.0, 0, 20, 0]]), [1.0], param_in="SPHERICAL_TL_PL_TV_PV",
                     param_out="INV_STERADIAN")
    args = _parser().parse_args(["import", str(src), "--out", str(tmp_path / "ds"), "--sample-id", "X"])
    assert args.func(args) == 0
    assert "1 points, 0 skipped" in capsys.readouterr().err
    assert args.func(args) == 2                      # the folder exists now: nothing overwritten
    assert "already exists" in capsys.readouterr().err
    bad = tmp_path / "bad.alta"
    bad.write_text("#DIM 4 1\n0 0 0 oops 1\n")
    args = _parser().parse_args(["import", str(bad), "--out", str(tmp_path / "ds2")])
    assert args.func(args) == 2
    assert f"{bad}:2: not a number: 'oops'" in capsys.readouterr().err
    assert not (tmp_path / "ds2").exists()


def test_skipped_csv_names_the_source_line(imported, cea_dir):
    with open(imported["yellow"].path / "skipped.csv", newline="") as fh:
        first = next(csv.DictReader(fh))
    assert first["point_id"] == "00-L8"                # line 8: the first data row, θV = 90°
    assert (cea_dir / TAPES["yellow"]).read_text().splitlines()[7].startswith("0.2617993877991494")
