"""Shared paths for the tests: everything they read lies inside the repository."""

from pathlib import Path

import pytest
from repo_paths import CAMPAIGNS, ROOT, TEST_CAMPAIGNS


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
