"""Radiance from the data of a sparse campaign (issue 31): five incidences 20° apart at φi = 0 plus two turned series
(tests/campaigns/sparse-five.yaml, the paper's Table 2 views), with RM1's closed-form values and 0.3 % noise. Handed
the measured series, pabopto2bsdf cannot follow the lobes across 20° and is 12.7 % (median) from the truth at the
paper table's directions; handed the reconstruction on a dense grid (rig.analysis.resampled, what `rig export
--format radiance-xml` does for an isotropic sample) it is within 12 %."""

import warnings

import numpy as np
import pytest

from planned_datasets import RM1, planned_dataset
from repo_paths import CAMPAIGNS, TEST_CAMPAIGNS
from rig.analysis.resampled import resampled
from rig.analysis.validation import TruthPredictor

radiance = pytest.importorskip("rig.data.radiance")
pytest.importorskip("pyradiance", reason="pyradiance (Radiance's tools) is a test dependency: pip install -e '.[test]'")


@pytest.fixture(scope="module")
def sparse():
    return planned_dataset(path=TEST_CAMPAIGNS / "sparse-five.yaml", noise_rel=0.003)


def paper_errors(xml):
    """|f/f_true − 1| of the XML at the paper table's directions within the sparse campaign's θi range."""
    paper = planned_dataset()
    keep = paper["theta_i_deg"] <= 80.5
    a = np.stack([paper[c][keep] for c in ("theta_i_deg", "phi_i_deg", "theta_o_deg", "phi_o_deg")])
    return np.abs(radiance.evaluate_xml(xml, *a) / TruthPredictor("retrophong", RM1).predict(*a).brdf_per_sr - 1)


def test_the_reconstruction_on_a_grid_is_within_12_percent_where_the_measured_series_are_not(sparse, tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", radiance.SparseIncidenceWarning)
        radiance.export_radiance_xml(sparse, tmp_path / "measured.xml", source="data", isotropic=True)
    grid = resampled(sparse)
    assert len(np.unique(grid["theta_i_deg"])) == 17 and np.all(grid["phi_i_deg"] == 0)
    radiance.export_radiance_xml(grid, tmp_path / "grid.xml", source="data", isotropic=True)
    measured, rebuilt = paper_errors(tmp_path / "measured.xml"), paper_errors(tmp_path / "grid.xml")
    assert np.median(rebuilt) <= 0.12
    assert np.median(rebuilt) < np.median(measured)


def test_the_grid_spans_the_measured_incidences_and_views_on_both_sides_of_the_plane(sparse):
    grid = resampled(sparse)
    assert grid["theta_i_deg"].min() == pytest.approx(sparse["theta_i_deg"].min())
    assert grid["theta_i_deg"].max() == pytest.approx(sparse["theta_i_deg"].max())
    assert grid["theta_o_deg"].max() <= sparse["theta_o_deg"].max() + 1e-9
    assert (grid["phi_o_deg"] > 180).any() and (grid["phi_o_deg"] < 180).any()
    assert np.all(np.isfinite(grid["brdf_per_sr"])) and np.all(grid["brdf_per_sr"] > 0)
    assert str(CAMPAIGNS) not in str(grid.path)
