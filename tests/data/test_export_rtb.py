"""`rig export --format rtb`: the DIALux r-table, read back with a reader written from DIAL's published layout
(support article 9000073306, "R-tables in DIALux": line 1 `RTable.v1`, line 2 the name, then the number of
tan ε values and one value per line, the number of β values and one per line, q0, then the r values with tan ε
varying fastest), equal to the road.json of the same fit; and `--format road`'s terminal summary."""

import contextlib
import io
import json
import math
from pathlib import Path

import pytest

from rig.cli.main import main
from rig.data.rtb import RtbError, road_summary, rtb_lines


def read_rtb(path: Path) -> dict:
    lines = path.read_text(encoding="utf-8").splitlines()
    assert lines[0] == "RTable.v1"
    k = 2
    n_eps = int(lines[k])
    tan_eps = [float(v) for v in lines[k + 1:k + 1 + n_eps]]
    k += 1 + n_eps
    n_beta = int(lines[k])
    beta = [float(v) for v in lines[k + 1:k + 1 + n_beta]]
    k += 1 + n_beta
    q0 = float(lines[k])
    values = [float(v) for v in lines[k + 1:]]
    assert len(values) == n_eps * n_beta
    r = [[values[j * n_eps + i] for j in range(n_beta)] for i in range(n_eps)]      # tan ε fastest
    return {"name": lines[1], "tan_eps": tan_eps, "beta": beta, "q0": q0, "r": r}


#: RetroPhong RM1 (Spieringhs et al. 2023 Table 7): an r-table that varies with β as well as tan γ, so that a
#: transposed layout would show.
FIT = {"model": "retrophong", "params": {"kd": 0.620, "n": 24.0, "k1": 0.158, "k2": 0.0415, "k3": 0.00133,
                                         "k4": 5.47}}


@pytest.fixture(scope="module")
def exported(tmp_path_factory):
    """A small dataset (45 points: the model's predictor consults the measured domain, which costs per point), the
    fit, and `rig export --format road` (its stdout kept) and `--format rtb` of it."""
    tmp = tmp_path_factory.mktemp("rtb")
    rows = [f"{math.radians(ti)!r} 0.0 {math.radians(to)!r} {math.radians(po)!r} 0.1"
            for ti in (10, 40, 70) for to in (5, 20, 35, 50, 65) for po in (0, 90, 180)]
    (tmp / "s.alta").write_text("#DIM 4 1\n#PARAM_IN SPHERICAL_TL_PL_TV_PV\n#PARAM_OUT INV_STERADIAN\n#VS 0\n"
                                '#SAMPLE "RM1\tmodel"\n' + "\n".join(rows) + "\n")
    assert main(["import", str(tmp / "s.alta"), "--out", str(tmp / "ds")]) == 0
    (tmp / "fit.json").write_text(json.dumps(FIT))
    common = ["export", str(tmp / "ds"), "--fit", str(tmp / "fit.json")]
    with contextlib.redirect_stdout(io.StringIO()) as stdout:
        assert main([*common, "--format", "road", "--out", str(tmp / "road.json")]) == 0
    assert main([*common, "--format", "rtb", "--out", str(tmp / "s.rtb")]) == 0
    return {"rtb": read_rtb(tmp / "s.rtb"), "road": json.loads((tmp / "road.json").read_text()),
            "stdout": stdout.getvalue(), "dataset": tmp / "ds"}


def test_rtb_reads_back_equal_to_road_json(exported):
    rtb, road = exported["rtb"], exported["road"]
    assert rtb["name"] == "RM1 model"                                         # the sample id, on one line
    assert (len(rtb["tan_eps"]), len(rtb["beta"])) == (29, 20)
    assert rtb["tan_eps"] == road["r_table"]["tan_gamma"] and rtb["beta"] == road["r_table"]["beta_deg"]
    assert rtb["q0"] == road["Q0"]
    assert rtb["r"] == road["r_table"]["r_x1e4"]
    assert rtb["r"][8][0] != rtb["r"][8][19]                                  # varies with β: the order matters


def test_an_undefined_cell_is_refused_naming_it(exported):
    road = json.loads(json.dumps(exported["road"]))
    road["r_table"]["r_x1e4"][3][7] = None
    with pytest.raises(RtbError, match=r"r_table.r_x1e4\[3\]\[7\] \(tan γ 0.75, β 30°\) is None"):
        rtb_lines(road, "x")


def test_format_road_prints_its_values(exported):
    road, printed = exported["road"], exported["stdout"]
    assert printed.splitlines() == road_summary(road)
    assert printed.startswith(f"R_L = {road['R_L_mcd_m2_lx']:.4g} ± {road['u_R_L_mcd_m2_lx']:.2g} mcd")
    assert f"Qd  = {road['Qd_mcd_m2_lx']:.4g} ± " in printed
    assert f"Q0  = {road['Q0']:.4g} ± {road['u_Q0']:.2g}" in printed
    assert f"S1  = {road['S1']:.4g} ± {road['u_S1']:.2g}" in printed
    assert f"class {road['marking_classes']['R_L']} (k = 2 range: " in printed
    for family, cls in road["surface_classes"].items():
        assert f"{family}: class {cls} (k = 2 range: " in printed


def test_rtb_needs_a_model(exported, tmp_path, capsys):
    out = tmp_path / "x.rtb"
    assert main(["export", str(exported["dataset"]), "--format", "rtb", "--out", str(out)]) == 2
    assert "--format rtb needs a model" in capsys.readouterr().err and not out.exists()
