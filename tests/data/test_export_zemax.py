"""`rig export --format zemax`: the tabular BSDF read back by a reader written from the public specification
(Zemax knowledge-base article 1500005486801, "Zemax Tabular BSDF data file format", formerly "BSDF Data
Interchange File Format Specification", R. Rykowski 2008), not from our writer:

- header keywords, each enumeration a count and a list; `DataBegin`, per sample rotation × incidence a `TIS` line
  and the table (rows: azimuths, columns: radial angles), `DataEnd`; `#` lines are comments;
- the scatter angles are measured about the specular direction: radial 0° is the specular direction, the radial
  angle the angle from it; azimuth 0° points from the specular direction toward the sample's normal;
  PlaneSymmetrical: the data are symmetric about the plane of incidence (azimuths 0–180°).

The reader interpolates as a consumer would (bilinear in azimuth and radial angle, linear between incidences)."""

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from planned_datasets import RM1, planned_dataset
from rig.analysis.smooth_views import smooth_predictor
from rig.cli.main import main
from rig.data.zemax import AZIMUTH_DEG, FormulaPredictor, ZemaxGrid, table, table_albedo
from rig.physics.brdf_models import albedo, get_model

#: A fit with the yellow retroreflective tape's published MRM values (Portsmouth 2026: roughness 0.23, F0 0.19)
#: over a Lambertian base: a narrow retroreflective lobe (FWHM about 5° in the plane of incidence).
FIT = {"model": "mrm_diffuse", "params": {"kd": 0.3, "roughness": 0.23, "f0": 0.19}}


@dataclass
class Tabular:
    header: dict[str, str]
    incidence: np.ndarray
    azimuth: np.ndarray
    radial: np.ndarray
    tis: np.ndarray
    data: np.ndarray            # (incidence, azimuth, radial)


def read_tabular(path: Path) -> Tabular:
    lines = [ln.strip() for ln in path.read_text(encoding="ascii").splitlines() if not ln.startswith("#")]
    header: dict[str, str] = {}
    lists: dict[str, np.ndarray] = {}
    k = 0
    while lines[k] != "DataBegin":
        if not lines[k]:
            k += 1
            continue
        key, *rest = lines[k].split()
        if key in ("SampleRotation", "AngleOfIncidence", "ScatterAzimuth", "ScatterRadial"):
            lists[key] = np.array(lines[k + 1].split(), float)
            assert len(lists[key]) == int(rest[0]), key
            k += 2
        else:
            header[key] = rest[0] if rest else ""
            k += 1
    assert lines[-1] == "DataEnd"
    tokens = " ".join(lines[k + 1:-1]).split()
    n_a, n_r = len(lists["ScatterAzimuth"]), len(lists["ScatterRadial"])
    blocks = len(lists["SampleRotation"]) * len(lists["AngleOfIncidence"])
    assert len(tokens) == blocks * (2 + n_a * n_r)
    tis, data = [], []
    for b in range(blocks):
        chunk = tokens[b * (2 + n_a * n_r):(b + 1) * (2 + n_a * n_r)]
        assert chunk[0] == "TIS"
        tis.append(float(chunk[1]))
        data.append(np.array(chunk[2:], float).reshape(n_a, n_r))
    return Tabular(header, lists["AngleOfIncidence"], lists["ScatterAzimuth"], lists["ScatterRadial"],
                   np.array(tis), np.array(data))


def _bilinear(table: np.ndarray, azimuth: np.ndarray, radial: np.ndarray, a: np.ndarray, r: np.ndarray):
    i = np.clip(np.searchsorted(azimuth, a) - 1, 0, len(azimuth) - 2)
    j = np.clip(np.searchsorted(radial, r) - 1, 0, len(radial) - 2)
    u = np.clip((a - azimuth[i]) / (azimuth[i + 1] - azimuth[i]), 0, 1)
    v = np.clip((r - radial[j]) / (radial[j + 1] - radial[j]), 0, 1)
    return ((1 - u) * (1 - v) * table[i, j] + u * (1 - v) * table[i + 1, j] + (1 - u) * v * table[i, j + 1]
            + u * v * table[i + 1, j + 1])


def specular_angles(theta_i: np.ndarray, wo: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(azimuth, radial) in degrees of wo about the specular direction of light at θi in the plane y = 0 (x > 0)."""
    t = np.radians(theta_i)[..., None]
    s = np.concatenate([-np.sin(t), np.zeros_like(t), np.cos(t)], axis=-1)      # specular direction
    n = np.array([0.0, 0.0, 1.0])
    e1 = n - np.sum(n * s, axis=-1, keepdims=True) * s                           # toward the normal
    e1 /= np.linalg.norm(e1, axis=-1, keepdims=True)
    e2 = np.cross(s, e1)
    radial = np.degrees(np.arccos(np.clip(np.sum(wo * s, axis=-1), -1, 1)))
    azimuth = np.degrees(np.abs(np.arctan2(np.sum(wo * e2, axis=-1), np.sum(wo * e1, axis=-1))))
    return azimuth, radial


def sample(t: Tabular, theta_i: np.ndarray, wo: np.ndarray) -> np.ndarray:
    """The table's BRDF at incidences θi (degrees, in the plane y = 0) and outgoing unit vectors wo."""
    a, r = specular_angles(theta_i, wo)
    k = np.clip(np.searchsorted(t.incidence, theta_i) - 1, 0, len(t.incidence) - 2)
    w = (theta_i - t.incidence[k]) / (t.incidence[k + 1] - t.incidence[k])
    out = np.empty(len(theta_i))
    for row in np.unique(k):
        at = k == row
        lo = _bilinear(t.data[row], t.azimuth, t.radial, a[at], r[at])
        hi = _bilinear(t.data[row + 1], t.azimuth, t.radial, a[at], r[at])
        out[at] = (1 - w[at]) * lo + w[at] * hi
    return out


def reader_albedo(t: Tabular, theta_i: float, n: int = 400) -> float:
    """∫ f cos θo dω of the interpolated table over the hemisphere (midpoint rule in azimuth and radial angle)."""
    psi = (np.arange(n) + 0.5) * 180.0 / n
    rho = (np.arange(2 * n) + 0.5) * 180.0 / (2 * n)
    pp, rr = np.meshgrid(np.radians(psi), np.radians(rho), indexing="ij")
    ti = math.radians(theta_i)
    s = np.array([-math.sin(ti), 0.0, math.cos(ti)])
    e1 = np.array([math.cos(ti), 0.0, math.sin(ti)])
    e2 = np.cross(s, e1)
    wo = (np.cos(rr)[..., None] * s + np.sin(rr)[..., None] * (np.cos(pp)[..., None] * e1
                                                               + np.sin(pp)[..., None] * e2))
    k = min(max(int(np.searchsorted(t.incidence, theta_i)) - 1, 0), len(t.incidence) - 2)
    w = (theta_i - t.incidence[k]) / (t.incidence[k + 1] - t.incidence[k])
    a, r = np.degrees(pp), np.degrees(rr)
    f = (1 - w) * _bilinear(t.data[k], t.azimuth, t.radial, a, r) + w * _bilinear(t.data[k + 1], t.azimuth,
                                                                                  t.radial, a, r)
    g = f * np.maximum(wo[..., 2], 0.0) * np.sin(rr)
    return float(2.0 * g.sum() * math.radians(180.0 / n) * math.radians(180.0 / (2 * n)))


@pytest.fixture(scope="module")
def exported(e2e_run, tmp_path_factory):
    tmp = tmp_path_factory.mktemp("zemax")
    (tmp / "fit.json").write_text(json.dumps(FIT))
    out = tmp / "tape.bsdf"
    assert main(["export", str(e2e_run), "--format", "zemax", "--source", "model", "--fit", str(tmp / "fit.json"),
                 "--out", str(out)]) == 0
    return read_tabular(out)


def _truth(theta_i: np.ndarray, wo: np.ndarray) -> np.ndarray:
    t = np.radians(theta_i)[..., None]
    wi = np.concatenate([np.sin(t), np.zeros_like(t), np.cos(t)], axis=-1)
    return get_model(FIT["model"])(wi, wo, FIT["params"])


def test_header_says_what_the_spec_asks(exported):
    assert exported.header == {"Source": "Measured", "Symmetry": "PlaneSymmetrical", "SpectralContent": "Monochrome",
                               "ScatterType": "BRDF", "Monochrome": ""}
    assert exported.azimuth[0] == 0 and exported.azimuth[-1] == 180
    assert exported.radial[0] == 0 and exported.incidence[0] == 0 and exported.incidence[-1] == 89
    # rows follow the retroreflective lobe: it moves 2° of radial angle per degree of incidence
    assert np.diff(exported.incidence).max() <= 1.0 + 1e-9


def test_reader_samples_the_model_within_3_percent(exported):
    rng = np.random.default_rng(37)
    n = 3000
    theta_i = rng.uniform(0.5, 85.0, n)
    mu, phi = rng.uniform(0.02, 1.0, n), rng.uniform(0, 2 * np.pi, n)
    wo = np.stack([np.sqrt(1 - mu ** 2) * np.cos(phi), np.sqrt(1 - mu ** 2) * np.sin(phi), mu], axis=-1)
    err = np.abs(sample(exported, theta_i, wo) / _truth(theta_i, wo) - 1)
    assert np.median(err) < 0.03, np.median(err)
    # the retroreflective peak itself, halfway between two incidence rows
    theta = np.array([20.5, 40.5, 60.5, 80.5])
    t = np.radians(theta)[:, None]
    wi = np.concatenate([np.sin(t), np.zeros_like(t), np.cos(t)], axis=-1)
    peak = np.abs(sample(exported, theta, wi) / _truth(theta, wi) - 1)
    assert peak.max() < 0.08, peak          # 5 % here


@pytest.mark.parametrize("theta_i", [10.0, 30.5, 60.0, 75.5])
def test_albedo_within_half_a_percent(exported, theta_i):
    truth = float(albedo(get_model(FIT["model"]), FIT["params"], theta_i))
    assert reader_albedo(exported, theta_i) == pytest.approx(truth, rel=0.005)
    if theta_i in exported.incidence:           # the TIS line: the table's own integral
        row = int(np.flatnonzero(exported.incidence == theta_i)[0])
        assert exported.tis[row] == pytest.approx(truth, rel=0.005)


def test_zemax_refusals(e2e_run, tmp_path, capsys):
    out = tmp_path / "x.bsdf"
    assert main(["export", str(e2e_run), "--format", "zemax", "--source", "model", "--out", str(out)]) == 2
    assert "--source model takes --fit" in capsys.readouterr().err and not out.exists()


def test_albedo_from_the_paper_views_at_grazing_incidence():
    """--source data on the paper campaign's views (Table 2's rings, 16-18 deg apart beyond 20 deg) at its grazing
    incidences, with RM1's exact values there: the table's albedo (its TIS) within 0.5 % of the truth's. A
    piecewise-linear interpolant of ln f between the rings cuts chords under the lobes' convex tails: +0.83 % at
    80 deg and +1.03 % at 85 deg from these very values (`rig predict`'s; the export before issue 37's fix). The C1
    cubic of rig.analysis.smooth_views: +0.03 % and -0.08 %."""
    predictor = smooth_predictor(planned_dataset(drop=lambda theta_i, theta_o, dphi: theta_i < 75))
    # the export's azimuths, radial angles 1 deg apart (the truth on this grid is within 0.05 % of its albedo)
    grid = ZemaxGrid(np.array([80.0, 85.0]), AZIMUTH_DEG, np.arange(181.0), math.inf, math.inf)
    truth = FormulaPredictor("retrophong", RM1)
    for theta_i in grid.incidence_deg:
        f, beyond = table(predictor, theta_i, grid)
        albedo_true = table_albedo(table(truth, theta_i, grid)[0], theta_i, grid)
        assert albedo_true == pytest.approx(float(albedo(get_model("retrophong"), RM1, theta_i)), rel=5e-4)
        assert table_albedo(f, theta_i, grid) == pytest.approx(albedo_true, rel=0.005), theta_i
        assert 0 < table_albedo(np.where(beyond, f, 0.0), theta_i, grid) < 0.1 * albedo_true    # 7 % not measured


def test_from_the_data_of_a_simulated_campaign(e2e_run, tmp_path, capsys):
    """--source data: the reconstruction of the reduced end-to-end campaign (four incidences, sparse views) against
    the simulated sample's own BRDF (retrophong, tests/campaigns/e2e-reduced.yaml): median within 12 % (7 % here).
    Its albedo is not the truth's within 0.5 % (3 to 41 %: docs/zemax.md, benchmarks/zemax_albedo.py): 40 to 60 %
    of each row's albedo lies where the campaign never looked, and the export says so; what the file holds, a
    reader integrates to its TIS."""
    import yaml

    campaign = yaml.safe_load(Path(__file__).parents[1].joinpath("campaigns", "e2e-reduced.yaml").read_text())
    truth = campaign["sample"]["simulated_brdf"]
    out = tmp_path / "data.bsdf"
    assert main(["export", str(e2e_run), "--format", "zemax", "--out", str(out)]) == 0
    table = read_tabular(out)
    assert table.incidence[-1] == 85
    rng = np.random.default_rng(31)
    n = 3000
    theta_i = rng.uniform(0.5, 84.0, n)
    mu, phi = rng.uniform(0.02, 1.0, n), rng.uniform(0, 2 * np.pi, n)
    wo = np.stack([np.sqrt(1 - mu ** 2) * np.cos(phi), np.sqrt(1 - mu ** 2) * np.sin(phi), mu], axis=-1)
    t = np.radians(theta_i)[..., None]
    wi = np.concatenate([np.sin(t), np.zeros_like(t), np.cos(t)], axis=-1)
    f = get_model(truth["model"])(wi, wo, truth["params"])
    assert np.median(np.abs(sample(table, theta_i, wo) / f - 1)) < 0.12
    err = capsys.readouterr().err
    share = int(err.split("they carry up to ")[1].split("%")[0])
    assert 40 <= share <= 100, err
    assert "# share of each TIS from cells beyond the measured domain" in out.read_text(encoding="ascii")[:2000]
    for theta in (40.0, 80.0):
        row = int(np.flatnonzero(table.incidence == theta)[0])
        assert reader_albedo(table, theta) == pytest.approx(table.tis[row], rel=0.005)


def test_grid_follows_the_lobes():
    """No lobe (Lambert): the coarsest grid; a narrow retroreflective lobe: rows and radial steps at their finest."""
    from rig.data.zemax import FormulaPredictor, grid_for

    flat = grid_for(FormulaPredictor("lambert", {"kd": 0.5}), 85.0)
    assert math.isinf(flat.retro_width_deg) and math.isinf(flat.specular_width_deg)
    assert set(np.diff(flat.incidence_deg)) == {5.0} and np.diff(flat.radial_deg).max() == 1.0
    narrow = grid_for(FormulaPredictor("mrm", {"roughness": 0.1, "f0": 0.5}), 85.0)
    assert narrow.retro_width_deg < 2.0 and math.isinf(narrow.specular_width_deg)      # MRM: no mirror lobe
    assert np.diff(narrow.incidence_deg).max() == 0.5 and np.diff(narrow.radial_deg[narrow.radial_deg > 10]).max() \
        == 0.25


def test_the_barycentric_transforms_are_scipys():
    """rig.analysis.smooth_views computes a triangulation's barycentric transforms in numpy (scipy's LAPACK loop took
    6-11 s under load): the same values, and the ones scipy's interpolant then uses (not recomputed)."""
    from scipy.spatial import Delaunay

    from rig.analysis.smooth_views import with_transforms

    points = np.random.default_rng(5).random((300, 2))
    mesh = with_transforms(Delaunay(points))
    assert mesh.transform is mesh._transform
    assert np.allclose(mesh.transform, Delaunay(points).transform, rtol=1e-9, atol=1e-9)
