"""Shared fixtures: the repository's paths (everything the tests read lies inside it) and the dataset of one
run of the reduced end-to-end campaign, which the CLI, export and plot tests read but never change."""

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
