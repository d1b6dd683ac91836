"""`rig export`: ALTA round trip, Radiance pabopto2bsdf files, CSV, road-lighting quantities."""

import argparse
import csv
from pathlib import Path

import numpy as np
import pytest

from rig.cli import export as export_cli
from rig.data import export as ex
from rig.data.alta import read_alta
from rig.data.dataset_reader import load
from rig.data.importer import import_alta


@pytest.fixture(scope="module")
def dataset(e2e_dataset):
    return e2e_dataset


def _angles(ds):
    return np.stack([ds[c] for c in ex.ANGLE_COLUMNS], axis=1)


def test_alta_round_trip(dataset, tmp_path):
    (path,) = ex.export(dataset, "alta", tmp_path / "d.alta")
    data = read_alta(path)
    assert (data.n_in, data.n_out, data.vs) == (4, 1, 1)
    assert (data.param_in, data.param_out) == ("SPHERICAL_TL_PL_TV_PV", "INV_STERADIAN")
    assert data.header["SAMPLE"] == '"RM1-sim"'
    assert np.allclose(np.degrees(data.x), _angles(dataset), rtol=0, atol=1e-12)       # radians in the file
    assert np.array_equal(data.x, np.radians(_angles(dataset)))
    assert np.array_equal(data.y[:, 0], dataset["brdf_per_sr"])
    assert np.array_equal(data.ci[:, 0], dataset["u_brdf_per_sr"])                      # u(f) in the #VS column
    back = load(import_alta(path, tmp_path / "back"))                                   # and into a dataset again
    assert np.allclose(_angles(back), _angles(dataset), rtol=0, atol=1e-9)
    assert np.array_equal(back["brdf_per_sr"], dataset["brdf_per_sr"])
    assert np.array_equal(back["u_brdf_per_sr"], dataset["u_brdf_per_sr"])


def _table(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def test_csv_has_units_in_the_header(dataset, tmp_path):
    (path,) = ex.export(dataset, "csv", tmp_path / "d.csv")
    rows = _table(path)
    assert list(rows[0]) == ["point_id", "series", "theta_i [deg]", "phi_i [deg]", "theta_o [deg]", "phi_o [deg]",
                             "f_r [1/sr]", "u(f_r) [1/sr]", "flags"]
    assert [r["point_id"] for r in rows] == dataset.point_id
    assert np.array_equal([float(r["f_r [1/sr]"]) for r in rows], dataset["brdf_per_sr"])


def test_road_quantities_closed_forms():
    theta_i = np.array([0.0, 30.0, 60.0, 88.76, 80.0])
    phi_i = np.array([0.0, 10.0, 10.0, 0.0, 0.0])
    theta_o = np.array([20.0, 30.0, 40.0, 87.71, 60.0])
    phi_o = np.array([0.0, 10.0, 190.0, 0.0, 180.0])
    f, u = np.array([0.1, 2.0, 0.3, 1.0, 0.5]), np.array([0.01, 0.02, 0.03, 0.01, 0.0])
    rq = ex.measured_road_quantities(theta_i, phi_i, theta_o, phi_o, f, u)
    cos_i = np.cos(np.radians(theta_i))
    assert np.array_equal(rq["q"], f)
    assert np.allclose(rq["R_L_mcd"], 1e3 * f * cos_i) and np.allclose(rq["u_R_L_mcd"], 1e3 * u * cos_i)
    assert np.allclose(rq["r_1e4"], 1e4 * f * cos_i ** 3)
    assert np.allclose(rq["tan_gamma"], np.tan(np.radians(theta_i)))
    # β: undefined at normal incidence, 180° for a view back toward the light, 0° for forward scattering
    assert np.isnan(rq["beta_deg"][0]) and np.allclose(rq["beta_deg"][1:], [180, 0, 180, 0])
    assert rq["observation_angle_deg"][1] == pytest.approx(0.0, abs=1e-6)
    # EN 1436 "30 m" geometry: entrance 88.76°, observation angle 1.05° → f ≈ 46.2 R_L (R_L in cd·m⁻²·lx⁻¹)
    assert rq["observation_angle_deg"][3] == pytest.approx(1.05)
    assert f[3] / (rq["R_L_mcd"][3] / 1e3) == pytest.approx(46.2, abs=0.05)


def test_rl_file(dataset, tmp_path):
    (path,) = ex.export(dataset, "rl", tmp_path / "rl.csv")
    rows = _table(path)
    assert len(rows) == len(dataset)
    assert {"q at measured geometry [1/sr]", "R_L at measured geometry [mcd/m2/lx]", "r at measured geometry [1e-4/sr]",
            "beta [deg]", "tan_gamma [1]"} <= set(rows[0])
    cos_i = np.cos(np.radians(dataset["theta_i_deg"]))
    assert np.allclose([float(r["R_L at measured geometry [mcd/m2/lx]"]) for r in rows],
                       1e3 * dataset["brdf_per_sr"] * cos_i)
    normal = dataset["theta_i_deg"] < ex.POLE_DEG
    assert all((r["beta [deg]"] == "") == bool(n) for r, n in zip(rows, normal))


def test_refuses_to_overwrite_and_unknown_format(dataset, tmp_path):
    target = tmp_path / "x.csv"
    target.write_text("keep me")
    with pytest.raises(ex.ExportError, match="already exists"):
        ex.export(dataset, "csv", target)
    assert target.read_text() == "keep me"
    with pytest.raises(ValueError, match="unknown export format"):
        ex.export(dataset, "merl", tmp_path / "y")


def test_cli_export(dataset, tmp_path, capsys):
    parser = argparse.ArgumentParser(prog="rig")
    export_cli.add_subcommand(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(["export", str(dataset.path), "--format", "radiance", "--out", str(tmp_path / "r")])
    assert args.func(args) == 0 and "4 files" in capsys.readouterr().err       # the two θi = 85° series merged
    assert args.func(args) == 2 and "already exists" in capsys.readouterr().err
    args = parser.parse_args(["export", str(tmp_path / "nope"), "--format", "csv", "--out", str(tmp_path / "c")])
    assert args.func(args) == 2 and "not a dataset folder" in capsys.readouterr().err
