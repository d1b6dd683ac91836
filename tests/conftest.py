"""Shared fixtures: the repository's paths (everything the tests read lies inside it), the dataset of one
run of the reduced end-to-end campaign, which the CLI, export and plot tests read but never change, and one
run of the paper campaign with its closed-form truth."""

from pathlib import Path

import pytest

from repo_paths import CAMPAIGNS, E2E_CAMPAIGN, ROOT, TEST_CAMPAIGNS
from rig.data.dataset_reader import Dataset, load


@pytest.fixture
def campaigns_dir() -> Path:
    return CAMPAIGNS


@pytest.fixture
def test_campaigns_dir() -> Path:
    return TEST_CAMPAIGNS


@pytest.fixture(scope="session")
def cea_dir() -> Path:
    """The vendored CEA retroreflective tapes (ALTA project data, MPL-2.0; see its PROVENANCE.md)."""
    return ROOT / "tests" / "data" / "cea-retro"


@pytest.fixture(scope="session")
def e2e_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Dataset folder of `rig run` on the reduced end-to-end campaign (simulated rig); read-only."""
    from rig.cli.main import main  # here, not at the top: a test that needs no run does not import the CLI

    out = tmp_path_factory.mktemp("e2e") / "ds"
    assert main(["run", str(E2E_CAMPAIGN), "--out", str(out), "--quiet"]) == 0
    return out


@pytest.fixture(scope="session")
def e2e_dataset(e2e_run: Path) -> Dataset:
    """The e2e run's dataset, loaded."""
    return load(e2e_run)


#: Sample text that would run or load something if a report did not escape it (tests/report, tests/browser).
HOSTILE_SAMPLE = {"id": '<script>alert("rig")</script> & Co',
                  "description": "<img src=http://example.invalid/x.png onerror=alert(1)>"}


@pytest.fixture(scope="session")
def e2e_report(e2e_run: Path, tmp_path_factory: pytest.TempPathFactory) -> dict:
    """`rig report` of a copy of the e2e run whose sample has hostile text, with a fit and a road.json made by
    `rig fit` and `rig export`: the report's folder ("dir", with ds/, fit.json, road.json, report.html), its
    HTML, the fit, the road quantities and the hostile sample. Built once for tests/report and tests/browser."""
    import json
    import shutil

    from rig.cli.main import main

    tmp = tmp_path_factory.mktemp("report")
    ds = tmp / "ds"
    shutil.copytree(e2e_run, ds)
    manifest = json.loads((ds / "dataset.json").read_text())
    manifest["sample"] = dict(HOSTILE_SAMPLE)
    (ds / "dataset.json").write_text(json.dumps(manifest))
    assert main(["fit", str(ds), "--model", "retrophong", "--json", str(tmp / "fit.json")]) == 0
    assert main(["export", str(ds), "--format", "road", "--fit", str(tmp / "fit.json"),
                 "--out", str(tmp / "road.json")]) == 0
    assert main(["report", str(ds), "--out", str(tmp / "report.html"), "--fit", str(tmp / "fit.json"),
                 "--road", str(tmp / "road.json")]) == 0
    return {"html": (tmp / "report.html").read_text(encoding="utf-8"), "dir": tmp, "hostile": HOSTILE_SAMPLE,
            "fit": json.loads((tmp / "fit.json").read_text()), "road": json.loads((tmp / "road.json").read_text())}


@pytest.fixture(scope="session")
def paper_run(tmp_path_factory: pytest.TempPathFactory):
    """The paper campaign (campaigns/spieringhs2023-rm1.yaml: Tables 1 and 2, RetroPhong RM1) measured once on the
    simulated rig: its dataset and its simulated truth as a function of (ωi, ωo) arrays; read-only."""
    from rig.acquisition.run import run_campaign
    from rig.config.campaign import load_campaign
    from rig.config.rigfile import simulated_rig
    from rig.physics.brdf_models import get_model
    from rig.session.connect import open_campaign_rig

    campaign, rig = load_campaign(CAMPAIGNS / "spieringhs2023-rm1.yaml"), simulated_rig()
    out = tmp_path_factory.mktemp("paper") / "ds"
    assert run_campaign(campaign, rig, out, open_campaign_rig).status == "complete"
    truth = campaign.sample.simulated_brdf
    model = get_model(truth.model)
    return load(out), lambda wi, wo: model(wi, wo, truth.params)
