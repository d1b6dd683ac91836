"""`rig fit` prints each parameter's shared (correlated) standard uncertainty, not only the JSON (issue 34)."""

import numpy as np

from rig.analysis.fit import fit
from rig.cli.fit import format_comparison, format_report
from rig.physics.geometry import sph_to_vec


def lambert_fit(shared: float):
    rng = np.random.default_rng(0)
    wi = sph_to_vec(np.radians(rng.uniform(0, 80, 50)), np.radians(rng.uniform(0, 360, 50)))
    wo = sph_to_vec(np.radians(rng.uniform(0, 80, 50)), np.radians(rng.uniform(0, 360, 50)))
    f = 0.5 / np.pi * (1 + 0.003 * rng.standard_normal(50))
    return fit("lambert", wi, wo, f, np.full(50, 0.003 * 0.5 / np.pi), shared={"calibration": np.full(50, shared)})


def test_the_report_and_the_comparison_show_the_shared_part():
    r = lambert_fit(0.02)
    line = next(ln for ln in format_report(r).splitlines() if ln.strip().startswith("kd"))
    assert f"shared ± {r.stderr_correlated['kd']:.3g} (2.00%)" in line
    row = next(ln for ln in format_comparison([r]).splitlines() if ln.startswith("lambert"))
    assert f"kd {r.params['kd']:.3g} shared ± {r.stderr_correlated['kd']:.3g}" in row


def test_nothing_shared_prints_nothing():
    r = lambert_fit(0.0)
    assert "shared ±" not in format_report(r) and "shared ±" not in format_comparison([r])
