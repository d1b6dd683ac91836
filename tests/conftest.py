"""Shared paths for the tests."""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def campaigns_dir() -> Path:
    return ROOT / "campaigns"


@pytest.fixture
def test_campaigns_dir() -> Path:
    return ROOT / "tests" / "campaigns"
