"""Locating a view in an incidence's triangulation (rig.analysis.incidence_views): a degenerate triangle (three
collinear views, det 0) holds nothing and says nothing: its barycentric weights are inf − inf, which printed
"invalid value encountered in subtract" through every `rig bench sampling` run that met one."""

import warnings

import numpy as np
import pytest

from rig.analysis.incidence_views import IncidenceViews


def test_a_degenerate_triangle_is_skipped_without_a_warning():
    corners = np.array([[[0, 0], [1, 0], [2, 0]], [[0, 0], [1, 0], [0, 1]]], float)     # collinear, then a true one
    simplex, weights = np.full(1, -1), np.zeros((1, 3))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        IncidenceViews._first_holding(np.array([[0.2, 0.2]]), corners, np.array([[0, 1]]), simplex, weights,
                                      np.arange(1))
    assert simplex[0] == 1
    assert weights[0] == pytest.approx([0.6, 0.2, 0.2], abs=1e-12)
