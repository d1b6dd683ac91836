"""`rig export --format rtb`: the DIALux r-table, read back with a reader written from DIAL's published layout
(support article 9000073306, "R-tables in DIALux": line 1 `RTable.v1`, line 2 the name, then the number of
tan ε values and one value per line, the number of β values and one per line, q0, then the r values with tan ε
varying fastest), equal to the road.json of the same fit; and `--format road`'s terminal summary."""

import json
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


def test_rtb_reads_back_equal_to_road_json(e2e_report, tmp_path):
    folder = e2e_report["dir"]
    out = tmp_path / "rm1.rtb"
    assert main(["export", str(folder / "ds"), "--format", "rtb", "--fit", str(folder / "fit.json"),
                 "--out", str(out)]) == 0
    rtb, road = read_rtb(out), json.loads((folder / "road.json").read_text())
    assert rtb["name"] == " ".join(e2e_report["hostile"]["id"].split())              # the sample, on one line
    assert (len(rtb["tan_eps"]), len(rtb["beta"])) == (29, 20)
    assert rtb["tan_eps"] == road["r_table"]["tan_gamma"] and rtb["beta"] == road["r_table"]["beta_deg"]
    assert rtb["q0"] == road["Q0"]
    assert rtb["r"] == road["r_table"]["r_x1e4"]


def test_an_undefined_cell_is_refused_naming_it(e2e_report):
    road = json.loads((e2e_report["dir"] / "road.json").read_text())
    road["r_table"]["r_x1e4"][3][7] = None
    with pytest.raises(RtbError, match=r"r_table.r_x1e4\[3\]\[7\] \(tan γ 0.75, β 30°\) is None"):
        rtb_lines(road, "x")


def test_road_summary_gives_the_values_their_u_and_classes(e2e_report):
    road = e2e_report["road"]
    text = "\n".join(road_summary(road))
    assert f"R_L = {road['R_L_mcd_m2_lx']:.4g} ± {road['u_R_L_mcd_m2_lx']:.2g} mcd" in text
    assert f"Qd  = {road['Qd_mcd_m2_lx']:.4g} ± " in text and f"Q0  = {road['Q0']:.4g} ± {road['u_Q0']:.2g}" in text
    assert f"S1  = {road['S1']:.4g} ± {road['u_S1']:.2g}" in text
    assert f"class {road['marking_classes']['R_L']} (k = 2 range: " in text
    for family, cls in road["surface_classes"].items():
        assert f"{family}: class {cls} (k = 2 range: " in text


def test_rtb_needs_a_model(e2e_run, tmp_path, capsys):
    out = tmp_path / "x.rtb"
    assert main(["export", str(e2e_run), "--format", "rtb", "--out", str(out)]) == 2
    assert "--format rtb needs a model" in capsys.readouterr().err and not out.exists()
