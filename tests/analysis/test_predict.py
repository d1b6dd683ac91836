"""BRDF predictors (rig.analysis.predict) and `rig predict`: the interpolant returns the measurements where
they were taken and a smooth BRDF between them within its stated u, flags what lies beyond the measured
incidences and views; the model predictor's u is the delta method on the fit's covariance (closed form for
a Lambertian) plus the misfit and the shared calibration."""

import csv
from pathlib import Path

import numpy as np
import pytest
from shared import PHI_O, THETA_I, THETA_O, dataset, smooth_brdf

from rig.analysis.fit import fit
from rig.analysis.predict import (
    FittedModel,
    InterpolatingPredictor,
    ModelPredictor,
    measured_domain,
    model_predictor,
)
from rig.cli.main import main
from rig.data.alta import write_alta


def test_the_interpolant_returns_the_measurements_where_they_were_taken():
    ds = dataset()
    p = InterpolatingPredictor(measured_domain(ds)).predict(ds["theta_i_deg"], ds["phi_i_deg"],
                                                            ds["theta_o_deg"], ds["phi_o_deg"])
    assert np.allclose(p.brdf_per_sr, ds["brdf_per_sr"], rtol=1e-9)
    assert not p.extrapolated.any()
    assert np.all(p.u_brdf_per_sr >= 0.01 * p.brdf_per_sr * (1 - 1e-9))      # at least the measurement's u


def test_between_measurements_a_smooth_brdf_is_interpolated_within_its_u():
    rng = np.random.default_rng(3)
    n = 2000
    ti, to = rng.uniform(0, 60, n), rng.uniform(0, 70, n)
    pi_, po = rng.uniform(0, 360, n), rng.uniform(0, 360, n)
    ds = dataset(u_rel=0.0)
    p = InterpolatingPredictor(measured_domain(ds)).predict(ti, pi_, to, po)
    truth = smooth_brdf(ti, pi_, to, po)
    inside = ~p.extrapolated
    assert inside.mean() > 0.9                      # θi 0–60° and θo 0–70° as measured: the hull edges
    rel = np.abs(p.brdf_per_sr / truth - 1)[inside]
    assert np.median(rel) < 0.01 and rel.max() < 0.08
    assert np.mean(np.abs(p.brdf_per_sr - truth)[inside] <= 2 * p.u_brdf_per_sr[inside]) > 0.9


def test_isotropy_a_rotated_incidence_azimuth_predicts_the_same():
    ds = dataset(phi_i=0.0)
    pred = InterpolatingPredictor(measured_domain(ds))
    a = pred.predict(30.0, 0.0, 35.0, 200.0)
    b = pred.predict(30.0, 117.0, 35.0, 317.0)          # the same relative azimuth
    c = pred.predict(30.0, 0.0, 35.0, 160.0)            # mirrored about the plane of incidence
    assert float(a.brdf_per_sr) == pytest.approx(float(b.brdf_per_sr), rel=1e-12)
    assert float(a.brdf_per_sr) == pytest.approx(float(c.brdf_per_sr), rel=1e-12)


@pytest.mark.parametrize("direction, beyond", [
    ((70.0, 0.0, 30.0, 90.0), True),       # θi above the highest measured incidence
    ((30.0, 0.0, 80.0, 90.0), True),       # θo beyond the measured views
    ((30.0, 0.0, 45.0, 90.0), False),
])
def test_directions_beyond_the_measured_domain_are_flagged(direction, beyond):
    ds = dataset()
    for predictor in (InterpolatingPredictor(measured_domain(ds)),
                      ModelPredictor(FittedModel("lambert", {"kd": 0.6}, {"kd": {"kd": 1e-4}}), measured_domain(ds))):
        assert bool(predictor.predict(*direction).extrapolated) is beyond


def test_model_u_is_the_delta_method_on_the_covariance_plus_misfit_and_scale():
    """Lambertian f = kd/π: u(f) = u(kd)/π from the covariance, in quadrature with the relative terms."""
    fitted = FittedModel("lambert", {"kd": 0.6}, {"kd": {"kd": 0.003 ** 2}})
    p = ModelPredictor(fitted, None, discrepancy_rel=0.004, scale_u_rel=0.002).predict(30, 0, 40, 180)
    f = 0.6 / np.pi
    assert float(p.brdf_per_sr) == pytest.approx(f, rel=1e-12)
    assert float(p.u_brdf_per_sr) == pytest.approx(np.sqrt((0.003 / np.pi) ** 2 + (0.004 ** 2 + 0.002 ** 2) * f ** 2),
                                                   rel=1e-6)
    assert bool(p.extrapolated)                     # without a measured domain, everything is a guess


def test_an_undetermined_parameter_gives_an_infinite_u():
    fitted = FittedModel.from_json({"model": "lambert", "params": {"kd": 0.6}, "covariance": {"kd": {"kd": None}}})
    assert np.isinf(float(ModelPredictor(fitted, None).predict(30, 0, 40, 180).u_brdf_per_sr))


def test_a_fit_covariance_covers_the_truth():
    """Noisy Lambertian data, fitted with rig's fitter: the prediction's u covers kd/π at k = 2 over seeds."""
    z = []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        ds = dataset(value=lambda ti, pi_, to, po: np.full(ti.shape, 0.6 / np.pi), u_rel=0.02)
        noisy = ds["brdf_per_sr"] * (1 + 0.02 * rng.standard_normal(len(ds)))
        wi, wo = ds.directions()
        result = fit("lambert", wi, wo, noisy, ds["u_brdf_per_sr"], starts=1, seed=seed)
        assert set(result.covariance) == {"kd"}
        p = ModelPredictor(FittedModel.from_json(result.to_json()), None).predict(30, 0, 40, 180)
        z.append((float(p.brdf_per_sr) - 0.6 / np.pi) / float(p.u_brdf_per_sr))
    assert np.mean(np.abs(z) <= 2) >= 0.85 and 0.5 < np.std(z) < 1.6


def lambert_dataset(tmp_path) -> Path:
    """A Lambertian measurement as a dataset folder, through `rig import` (kd = 0.6)."""
    ti, to, po = (a.ravel() for a in np.meshgrid(np.radians(THETA_I), np.radians(THETA_O[1:]), np.radians(PHI_O),
                                                 indexing="ij"))
    x = np.c_[ti, np.zeros(ti.size), to, po]
    path = write_alta(tmp_path / "l.alta", x, np.full(len(x), 0.6 / np.pi), param_in="SPHERICAL_TL_PL_TV_PV",
                      param_out="INV_STERADIAN")
    assert main(["import", str(path), "--out", str(tmp_path / "ds")]) == 0
    return tmp_path / "ds"


def test_rig_predict_writes_the_columns_and_flags(tmp_path, capsys):
    ds = lambert_dataset(tmp_path)
    at = tmp_path / "at.csv"
    at.write_text("theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg\n30,0,35,100\n75,0,35,100\n", encoding="utf-8")
    for method, extra in (("interpolate", []), ("model", ["--model", "lambert"])):
        out = tmp_path / f"{method}.csv"
        capsys.readouterr()
        assert main(["predict", str(ds), "--at", str(at), "--out", str(out), "--method", method, *extra]) == 0
        assert method in capsys.readouterr().err
        with out.open() as fh:
            rows = list(csv.DictReader(fh))
        assert list(rows[0]) == ["theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg", "brdf_per_sr",
                                 "u_brdf_per_sr", "extrapolated"]
        assert [r["extrapolated"] for r in rows] == ["0", "1"]
        assert float(rows[0]["brdf_per_sr"]) == pytest.approx(0.6 / np.pi, rel=1e-6)


@pytest.mark.parametrize("text, message", [
    ("theta_i_deg,phi_i_deg,theta_o_deg\n1,2,3\n", "missing phi_o_deg"),
    ("theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg\n1,2,x,4\n", "line 2: theta_o_deg = 'x' is not a number"),
    ("theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg\n1,2,3,4\n95,2,3,4\n", "line 3: theta_i_deg = 95 is not allowed"),
    ("theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg\n", "no direction"),
])
def test_bad_directions_are_refused_naming_file_and_line(tmp_path, capsys, text, message):
    ds = lambert_dataset(tmp_path)
    at = tmp_path / "at.csv"
    at.write_text(text, encoding="utf-8")
    capsys.readouterr()
    assert main(["predict", str(ds), "--at", str(at), "--out", str(tmp_path / "p.csv")]) == 2
    err = capsys.readouterr().err
    assert message in err and str(at) in err and not (tmp_path / "p.csv").exists()


def one_direction(tmp_path: Path) -> Path:
    """A DIRECTIONS.csv of one direction."""
    at = tmp_path / "at.csv"
    at.write_text("theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg\n30,0,35,100\n", encoding="utf-8")
    return at


def test_the_model_method_needs_a_fit_or_a_model(tmp_path, capsys):
    ds, at = lambert_dataset(tmp_path), one_direction(tmp_path)
    assert main(["predict", str(ds), "--at", str(at), "--out", str(tmp_path / "p.csv"), "--method", "model"]) == 2
    assert "--fit FIT.json" in capsys.readouterr().err


def test_a_model_or_a_fit_implies_the_model_method_and_interpolate_refuses_them(tmp_path, capsys):
    ds, at = lambert_dataset(tmp_path), one_direction(tmp_path)
    assert main(["predict", str(ds), "--at", str(at), "--out", str(tmp_path / "m.csv"), "--model", "lambert"]) == 0
    assert "model lambert" in capsys.readouterr().err
    assert main(["predict", str(ds), "--at", str(at), "--out", str(tmp_path / "i.csv"), "--method", "interpolate",
                 "--model", "lambert"]) == 2
    assert "go with --method model" in capsys.readouterr().err


def test_model_predictor_from_a_dataset_fits_when_asked():
    ds = dataset(value=lambda ti, pi_, to, po: np.full(ti.shape, 0.6 / np.pi), u_rel=0.01)
    pred = model_predictor(ds, model="lambert")
    assert "lambert" in pred.method
    assert float(pred.predict(30, 0, 40, 180).brdf_per_sr) == pytest.approx(0.6 / np.pi, rel=1e-6)


def test_between_incidences_the_interpolant_follows_the_lobes():
    """lobe_aligned sends the retroreflection and mirror points of one incidence to another's, keeps the rim on the
    rim and the normal on the normal."""
    from rig.analysis.predict import lobe_aligned

    xy = np.array([[-np.sin(np.radians(40)), 0.0], [np.sin(np.radians(40)), 0.0], [0.0, 0.0], [0.0, 1.0],
                   [np.cos(np.radians(30)), 0.5]])
    out = lobe_aligned(xy, np.full(5, 40.0), 60.0)
    s60 = np.sin(np.radians(60))
    assert out[0] == pytest.approx([-s60, 0.0]) and out[1] == pytest.approx([s60, 0.0])
    assert out[2] == pytest.approx([0.0, 0.0]) and out[3] == pytest.approx([0.0, 1.0])
    assert np.hypot(*out[4]) == pytest.approx(1.0)
    assert lobe_aligned(xy, np.full(5, 40.0), 40.0) == pytest.approx(xy)


def test_outside_the_hull_the_interpolant_holds_the_value_at_the_nearest_point_of_its_edge():
    """ln f linear along the plane of incidence; a grazing view between the 30° and 60° rim views of the
    measured θo ≤ 70° hull lies nearest the middle of that edge: the value there is the mean of the two
    vertices' ln f, where the nearest vertex would give one of them."""
    def tilted(theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg):
        return 0.2 * np.exp(0.5 * np.sin(np.radians(theta_o_deg)) * np.cos(np.radians(phi_o_deg - phi_i_deg)))
    p = InterpolatingPredictor(measured_domain(dataset(tilted))).predict(20.0, 0.0, 80.0, 45.0)
    rim = np.sin(np.radians(70.0))
    edge_mid_x = rim * (np.cos(np.radians(30.0)) + np.cos(np.radians(60.0))) / 2
    assert bool(p.extrapolated)
    assert float(p.brdf_per_sr) == pytest.approx(0.2 * np.exp(0.5 * edge_mid_x), rel=1e-9)
