"""Leave one incidence out (rig.analysis.held_out): the interpolant `rig predict` uses chooses how to interpolate
between incidences on incidences it was not given, calibrates its between-incidence u there, and says so."""

import numpy as np
import pytest

from planned_datasets import planned_dataset
from rig.analysis.held_out import HeldOut, held_out, interpolating_predictor
from rig.analysis.predict import measured_domain


def test_the_scale_brings_the_95th_percentile_of_error_over_u_to_two():
    errors = np.linspace(0.0, 1.0, 101)
    assert HeldOut(errors, np.full(101, 0.5)).u_scale == pytest.approx(1.0)       # 2u = 1 covers them all
    assert HeldOut(errors, np.full(101, 0.1)).u_scale == pytest.approx(0.95 / 0.2)
    assert HeldOut(np.zeros(0), np.zeros(0)).u_scale == 1.0


def test_the_paper_table_interpolates_at_lobe_aligned_views_because_they_predict_left_out_incidences_better():
    ds = planned_dataset()
    domain = measured_domain(ds)
    aligned, fixed = held_out(domain, True), held_out(domain, False)
    assert aligned.error.size == fixed.error.size > 500
    assert aligned.rms < 0.8 * fixed.rms
    predictor = interpolating_predictor(ds)
    assert predictor.domain.aligned
    assert f"{aligned.rms:.3g} against {fixed.rms:.3g} at fixed views" in predictor.method
