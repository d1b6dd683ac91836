"""ALTA text files: writer/reader round trip, malformed input, conversion to rig angles."""

from pathlib import Path

import numpy as np
import pytest

from rig.data.alta import AltaError, read_alta, to_rig, write_alta
from rig.physics.geometry import sph_to_vec


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "f.alta"
    path.write_text(text)
    return path


@pytest.mark.parametrize("vs", [0, 1, 2])
def test_write_read_round_trip_is_exact(tmp_path, vs):
    rng = np.random.default_rng(vs)
    x = rng.uniform(0, 1.5, (40, 4))
    y = rng.lognormal(size=40)
    ci = None if vs == 0 else rng.uniform(0, 0.1, (40, vs)).squeeze()
    path = write_alta(tmp_path / "a.alta", x, y, param_in="SPHERICAL_TL_PL_TV_PV", param_out="INV_STERADIAN",
                      ci=ci, header={"SAMPLE": '"test"'}, comments=["made by a test"])
    data = read_alta(path)
    assert (data.n_in, data.n_out, data.vs) == (4, 1, vs)
    assert data.param_in == "SPHERICAL_TL_PL_TV_PV" and data.param_out == "INV_STERADIAN"
    assert data.header["SAMPLE"] == '"test"' and data.comments == ["made by a test"]
    assert np.array_equal(data.x, x) and np.array_equal(data.y[:, 0], y)
    assert np.array_equal(data.ci, np.empty((40, 0)) if ci is None else ci.reshape(40, vs))


def test_reader_accepts_comments_blank_lines_and_tabs(tmp_path):
    path = _write(tmp_path, "# a comment\n#DIM\t3 1\n#PARAM_IN ISOTROPIC_TL_TV_PROJ_DPHI\n\n"
                            "0.1\t0.2  0.3 4.5\n# between rows\n\n0.1 0.2 0.3 5\n")
    data = read_alta(path)
    assert len(data) == 2 and data.vs == 0 and data.param_out is None
    assert data.comments == ["a comment", "between rows"]
    assert list(data.line) == [5, 8]


@pytest.mark.parametrize("text, line, words", [
    ("#DIM 4\n#PARAM_IN SPHERICAL_TL_PL_TV_PV\n0 0 0 0 1\n", 1, "#DIM needs 2"),
    ("#DIM a b\n0 0 0 0 1\n", 1, "#DIM needs 2"),
    ("#DIM 4 1\n#VS 3\n0 0 0 0 1\n", 2, "#VS must be 0, 1 or 2"),
    ("#DIM 3 1\n#PARAM_IN SPHERICAL_TL_PL_TV_PV\n0 0 0 1\n", 1, "has 4 inputs"),
    ("#DIM 4 1\n#PARAM_IN NO_SUCH\n0 0 0 0 1\n", 2, "unknown #PARAM_IN"),
    ("#DIM 4 1\n#PARAM_OUT LUMENS\n0 0 0 0 1\n", 2, "unknown #PARAM_OUT"),
    ("#DIM 4 1\n#VS 1\n0 0 0 0 1 0.1\n0 0 0 0 1\n", 4, "expected 6 columns"),
    ("#DIM 4 1\n0 0 0 0 1\n0 0 x 0 1\n", 3, "not a number: 'x'"),
    ("#DIM 4 1\n0 0 0 0 nan\n", 2, "non-finite"),
    ("#DIM 4 1\n#DIM 4 1\n0 0 0 0 1\n", 2, "#DIM given twice"),
])
def test_reader_errors_name_file_and_line(tmp_path, text, line, words):
    path = _write(tmp_path, text)
    with pytest.raises(AltaError) as err:
        read_alta(path)
    assert f"{path}:{line}:" in str(err.value) and words in str(err.value)


def test_reader_needs_dim(tmp_path):
    path = _write(tmp_path, "#PARAM_IN SPHERICAL_TL_PL_TV_PV\n0 0 0 0 1\n")
    with pytest.raises(AltaError, match=f"{path}: no #DIM"):
        read_alta(path)


def _points(tmp_path, x, y, param_in, param_out, ci=None):
    return to_rig(read_alta(write_alta(tmp_path / "c.alta", x, y, param_in=param_in,
                                       param_out=param_out, ci=ci)))


def test_projected_dphi_puts_retroreflection_at_dphi_zero(tmp_path):
    tl, tv = np.radians(30.0), np.radians(20.0)
    x = np.array([[tl, tl, 0.0],            # retroreflection
                  [tl, -tl, 0.0],           # mirror direction
                  [tl, 0.0, tv],            # Δφ = +90°
                  [tl, 0.0, 0.0]])          # normal view
    p = _points(tmp_path, x, np.ones(4), "ISOTROPIC_TL_TV_PROJ_DPHI", "INV_STERADIAN")
    a = p.angles
    assert np.allclose(a.theta_i_deg, 30.0) and np.allclose(a.phi_i_deg, 0.0)
    assert np.allclose(a.theta_o_deg, [30, 30, 20, 0]) and np.allclose(a.phi_o_deg, [0, 180, 90, 0])
    wi = sph_to_vec(np.radians(a.theta_i_deg), np.radians(a.phi_i_deg))
    wo = sph_to_vec(np.radians(a.theta_o_deg), np.radians(a.phi_o_deg))
    assert np.allclose(wo[0], wi[0]) and np.allclose(wo[1], wi[1] * [-1, -1, 1])
    assert list(p.reason) == ["", "", "", ""] and p.u_brdf is None


def test_spherical_angles_carry_over_with_phi_wrapped(tmp_path):
    x = np.radians([[40.0, -90.0, 10.0, 370.0]])
    a = _points(tmp_path, x, [0.5], "SPHERICAL_TL_PL_TV_PV", "INV_STERADIAN").angles
    assert np.allclose([a.theta_i_deg[0], a.phi_i_deg[0], a.theta_o_deg[0], a.phi_o_deg[0]], [40, 270, 10, 10])


def test_cosine_factor_divided_and_grazing_views_left_out(tmp_path):
    tl = np.radians(15.0)
    tv = np.radians([60.0, 89.5, 90.0])
    x = np.stack([np.full(3, tl), tv, np.zeros(3)], axis=1)
    p = _points(tmp_path, x, [0.5, 0.01, 0.001], "ISOTROPIC_TL_TV_PROJ_DPHI", "INV_STERADIAN_COSINE_FACTOR",
                ci=[0.05, 0.001, 0.001])
    assert list(p.reason) == ["", "cosine_factor_near_horizon", "below_horizon"]
    assert p.brdf[0] == pytest.approx(1.0) and p.u_brdf[0] == pytest.approx(0.1)
    assert np.all(np.isfinite(p.brdf))


def test_vs2_gives_half_the_segment_between_the_two_distances(tmp_path):
    """#VS 2 columns are distances below and above y (ALTA's loader): [1 − 0.1, 1 + 0.3] has half-width 0.2."""
    p = _points(tmp_path, np.radians([[10.0, 0, 20, 0]]), [1.0], "SPHERICAL_TL_PL_TV_PV", "INV_STERADIAN",
                ci=np.array([[0.1, 0.3]]))
    assert p.u_brdf[0] == pytest.approx(0.2)


def test_missing_param_out_needs_an_assumption(tmp_path):
    path = _write(tmp_path, "#DIM 3 1\n#PARAM_IN ISOTROPIC_TL_TV_PROJ_DPHI\n0.2 0.1 0 0.5\n")
    with pytest.raises(AltaError, match="no #PARAM_OUT"):
        to_rig(read_alta(path))
    p = to_rig(read_alta(path), assume_param_out="INV_STERADIAN_COSINE_FACTOR")
    assert p.param_out == "INV_STERADIAN_COSINE_FACTOR"
    assert any("assumed INV_STERADIAN_COSINE_FACTOR" in n for n in p.notes)
    assert p.brdf[0] == pytest.approx(0.5 / np.cos(0.1))


def test_unsupported_parametrization_is_refused(tmp_path):
    path = _write(tmp_path, "#DIM 3 1\n#PARAM_IN RUSIN_TH_TD_PD\n#PARAM_OUT INV_STERADIAN\n0.2 0.1 0 0.5\n")
    with pytest.raises(AltaError, match="RUSIN_TH_TD_PD cannot be imported"):
        to_rig(read_alta(path))
