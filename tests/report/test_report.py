"""`rig report` on the shared end-to-end run (`e2e_report`, tests/conftest.py: a copy of it with a hostile sample
name, with a fit and a road.json): every section there, the counts and the uncertainty budget equal to the
dataset's, the fit and road sections, text from files escaped, and one message for a dataset that cannot be read."""

import argparse
import json
import re
from html.parser import HTMLParser

import numpy as np
import pytest

from rig.cli import report as report_cli
from rig.data.dataset_reader import load
from rig.physics.budget import BUDGET_COLUMNS
from rig.report.content import FAULT_EVENTS, budget, conditions, read_events
from rig.report.html import with_u

SECTIONS = ("sample", "rig", "conditions", "counts", "budget", "figures", "fit", "road")


def rig_report(*argv: str) -> int:
    """`rig report ARGV` through the command's own parser (rig.cli.main registers the same function)."""
    parser = argparse.ArgumentParser()
    report_cli.add_subcommand(parser.add_subparsers())
    args = parser.parse_args(["report", *argv])
    return args.func(args)


@pytest.fixture(scope="module")
def made(e2e_report):
    """The report of a copy of the e2e run whose sample has hostile text, with a fit and a road.json (conftest)."""
    return e2e_report


class Links(HTMLParser):
    """Every URL-valued attribute of the page's tags (src, href, srcset, action, data, poster)."""

    def __init__(self, html: str) -> None:
        super().__init__()
        self.urls: list[str] = []
        self.feed(html)

    def handle_starttag(self, tag, attrs):
        self.urls += [v or "" for k, v in attrs if k in ("src", "href", "srcset", "action", "data", "poster")]


def section(html: str, ident: str) -> str:
    match = re.search(rf'<section id="{ident}"[^>]*>(.*?)</section>', html, re.S)
    assert match, f"section {ident} missing"
    return match.group(1)


def row(html: str, label: str) -> str:
    match = re.search(rf"<tr><th>{re.escape(label)}</th><td>(.*?)</td></tr>", html)
    assert match, f"row {label} missing"
    return match.group(1)


def test_every_section_and_figure_is_there(made, e2e_dataset):
    html = made["html"]
    for ident in SECTIONS:
        section(html, ident)
    images = re.findall(r"<img ([^>]*)>", html)
    n_series = len(np.unique(e2e_dataset["series"]))
    # polar map, E⊥ trend, plane and lobe per series, fit residuals
    assert len(images) == 2 + 2 * n_series + 1
    assert all(re.match(r'src="data:image/png;base64,[A-Za-z0-9+/=]{1000,}"', i) for i in images)
    urls = Links(html).urls
    assert len(urls) == len(images) and all(u.startswith("data:image/png;base64,") for u in urls)   # nothing to fetch
    assert "<script" not in html and "@media print" in html


def test_counts_equal_the_dataset(made, e2e_dataset):
    counts = section(made["html"], "counts")
    manifest = e2e_dataset.manifest["counts"]
    assert row(counts, "Measured") == str(len(e2e_dataset)) == str(manifest["measured"])
    assert row(counts, "Planned") == str(manifest["planned"])
    assert row(counts, "Skipped by the plan") == str(len(e2e_dataset.skipped))
    reasons = dict(re.findall(r"<tr><td><code>([a-z_:]+)</code></td><td class=\"num\">(\d+)</td></tr>", counts))
    expected = {}
    for r in e2e_dataset.skipped:
        expected[r["reason"]] = expected.get(r["reason"], 0) + 1
    assert {k: int(v) for k, v in reasons.items()} == expected and sum(expected.values()) == 40


def test_budget_medians_and_p95_are_numpys(made, e2e_dataset):
    rows = budget(e2e_dataset)
    assert {b.component for b in rows} == set(BUDGET_COLUMNS)
    shown = section(made["html"], "budget")
    for b in rows:
        column = e2e_dataset[b.component]
        assert b.median_u_rel == pytest.approx(np.median(column), rel=1e-12, abs=1e-15)
        assert b.p95_u_rel == pytest.approx(np.percentile(column, 95), rel=1e-12, abs=1e-15)
        cells = re.search(rf"<code>{b.component}</code></td><td>.*?</td><td class=\"num\">([^<]*) %</td>"
                          rf"<td class=\"num\">([^<]*) %</td>", shown)
        assert cells, b.component
        assert float(cells.group(1)) == pytest.approx(100 * np.median(column), rel=5e-3, abs=1e-12)
        assert float(cells.group(2)) == pytest.approx(100 * np.percentile(column, 95), rel=5e-3, abs=1e-12)
    shares = [b.median_share for b in rows]
    assert shares == sorted(shares, reverse=True) and 0.5 < shares[0] <= 1


def test_fit_section_shows_the_fit(made):
    fit, shown = made["fit"], section(made["html"], "fit")
    assert fit["model"] in shown
    for name, value in fit["params"].items():
        assert f"<td>{name}</td><td class=\"num\">{with_u(value, fit['stderr'][name])}</td>" in shown
    for key in ("RMSE", "NRMSE", "NCC"):
        assert float(re.sub(r"[^0-9.e+-]", "", row(shown, key))) == pytest.approx(fit["metrics"][key.lower()],
                                                                                   rel=1e-3)


def test_road_section_shows_road_json(made):
    road, shown = made["road"], section(made["html"], "road")
    for key in ("R_L_mcd_m2_lx", "Qd_mcd_m2_lx", "Q0", "S1"):
        assert with_u(road[key], road[f"u_{key}"]) in shown
    assert road["surface_classes"]["R"] in shown and "extrapolated" in shown


def test_text_from_files_is_escaped(made):
    html = made["html"]
    assert made["hostile"]["id"] not in html and made["hostile"]["description"] not in html
    assert "&lt;script&gt;alert(&quot;rig&quot;)&lt;/script&gt; &amp; Co" in html
    assert "&lt;img src=http://example.invalid/x.png onerror=alert(1)&gt;" in html


def test_value_with_uncertainty_to_two_significant_digits():
    assert with_u(21.804624, 0.026112) == "21.805 ± 0.026"
    assert with_u(205.862, 0.2313) == "205.86 ± 0.23"
    assert with_u(1234.5, 56.0) == "1234 ± 56"            # two digits of u, the value to the same place
    assert with_u(0.62063, None) == "0.62063"


def test_conditions_count_pauses_and_faults(tmp_path):
    lines = [{"event": "warmup_stable", "warmup_s": 600.0, "change_rel": 0.001},
             {"event": "illuminance", "rig_time_s": 0.0, "illuminance_normal_lx": 5000.0, "u_lx": 4.0},
             {"event": "retry", "device": "camera"}, {"event": "retry", "device": "arm"},
             {"event": "suspended", "device": "lamp", "reason": "current 3.9 A"},
             {"event": "reconnect", "device": "meter"},
             {"event": "resumed", "device": "lamp", "waited_s": 42.0},
             {"event": "illuminance", "rig_time_s": 3600.0, "illuminance_normal_lx": 4990.0, "u_lx": 4.0},
             {"event": "suspended", "device": "meter", "reason": "E⊥ jump"}]
    text = "\n".join(json.dumps(e) for e in lines) + '\n{"event": "retry", "dev'       # a torn last line
    (tmp_path / "events.jsonl").write_text(text)
    c = conditions(read_events(tmp_path), {"resumes": [{"previous_status": "failed"}]})
    assert c.faults["retry"] == 2 and c.faults["reconnect"] == 1 and set(c.faults) == set(FAULT_EVENTS)
    assert [(p.device, p.waited_s) for p in c.pauses] == [("lamp", 42.0), ("meter", None)]
    assert c.resumes == 1 and c.warmup_stable and c.warmup_s == pytest.approx(600.0)
    assert c.illuminance.change_rel == pytest.approx(-0.002, rel=1e-9)
    assert c.illuminance.slope_rel_per_h == pytest.approx(-10.0 / 4995.0, rel=1e-9)


@pytest.mark.parametrize("garble", ["missing", "not_json"])
def test_a_dataset_that_cannot_be_read_gives_one_message(tmp_path, capsys, garble):
    ds = tmp_path / "ds"
    if garble == "not_json":
        ds.mkdir()
        (ds / "dataset.json").write_text("{not json")
    assert rig_report(str(ds), "--out", str(tmp_path / "r.html")) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(ds) in err and "Traceback" not in err
    assert not (tmp_path / "r.html").exists()


def test_an_existing_out_is_not_overwritten(made, e2e_run, capsys):
    out = made["dir"] / "report.html"
    before = out.read_bytes()
    assert rig_report(str(e2e_run), "--out", str(out)) == 2
    assert "already exists" in capsys.readouterr().err and out.read_bytes() == before


def test_the_dataset_loads_unchanged_after_the_report(made):
    assert len(load(made["dir"] / "ds")) > 0
