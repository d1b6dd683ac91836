"""Where the tests find what they read: everything lies inside the repository (this file is at
tests/repo_paths.py, so the repository is its parent's parent)."""

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: The campaigns shipped with rig (campaigns/) and the rig files under it.
CAMPAIGNS = ROOT / "campaigns"
RIGS = CAMPAIGNS / "rigs"
#: Campaigns made for the tests (tests/campaigns/).
TEST_CAMPAIGNS = ROOT / "tests" / "campaigns"
#: The small campaign most end-to-end tests run.
E2E_CAMPAIGN = TEST_CAMPAIGNS / "e2e-reduced.yaml"
