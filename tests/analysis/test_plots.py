"""`rig plot`: figures are written, readable, and put the retro lobe on the lamp side."""

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
from matplotlib.image import imread

from rig.analysis import plots
from rig.cli import plot
from rig.physics import geometry as geo

FIT_RGB = np.array([0xD6, 0x27, 0x28]) / 255          # plots.FITTED


@pytest.fixture(scope="module")
def dataset(e2e_dataset):
    return e2e_dataset


@pytest.fixture(scope="module")
def truth_fit(dataset):
    """A fit record built from the simulated truth, as `rig fit --json` would write it."""
    truth = dataset.manifest["simulated_brdf"]
    return {"model": truth["model"], "params": truth["params"], "metrics": {"rmse": 0.0, "nrmse": 0.0, "ncc": 1.0}}


@pytest.fixture(scope="module")
def figures(dataset, truth_fit, tmp_path_factory):
    return plots.plot_dataset(dataset, tmp_path_factory.mktemp("fig"), truth_fit)


def _fit_pixels(path: Path) -> np.ndarray:
    """Mask of pixels of the fitted curve's colour."""
    rgb = imread(path)[..., :3]
    return np.all(np.abs(rgb - FIT_RGB) < 0.08, axis=-1)


def test_figures_exist_and_are_not_trivial(figures):
    names = sorted(p.name for p in figures)
    incidences = ("ti00_pi000", "ti40_pi000", "ti80_pi000", "ti85_pi000", "ti85_pi023")   # θi and φi: s03 ≠ s04
    assert names == sorted([f"plane_s{s:02d}_{t}.png" for s, t in enumerate(incidences)]
                           + [f"lobe_s{s:02d}_{t}.png" for s, t in enumerate(incidences)] + ["fit_residuals.png"])
    for path in figures:
        assert path.stat().st_size > 30_000
        rgb = imread(path)[..., :3]
        assert np.mean(np.any(rgb < 0.9, axis=-1)) > 0.05          # far from a blank canvas


def test_fitted_retro_peak_is_drawn_on_the_lamp_side(figures):
    """θi = 40°: the highest point of the fitted curve in the Cartesian panel sits at +40°, not at the mirror."""
    (path,) = [p for p in figures if p.name == "plane_s01_ti40_pi000.png"]
    red = _fit_pixels(path)
    red[:, : red.shape[1] // 2] = False                             # the Cartesian panel (right half) only
    rows, cols = np.nonzero(red)
    top = cols[rows == rows.min()].mean()
    # the curve spans −89.5°…+89.5°: +40° lies at 0.72 of its width, the mirror (−40°) at 0.28
    assert (top - cols.min()) / (cols.max() - cols.min()) == pytest.approx(129.5 / 179, abs=0.03)


def test_without_fit_no_fitted_curve(dataset, tmp_path):
    path = plots.plot_plane(dataset, 1, tmp_path / "p.png")
    assert path.stat().st_size > 30_000
    assert _fit_pixels(path).sum() == 0
    empty = plots.plot_plane(dataset, 1, tmp_path / "e.png", tol_deg=1e-9)       # no view that close to the plane
    assert empty.stat().st_size > 20_000


def test_plane_offsets():
    t, n = geo.plane_axes(40.0, 90.0)
    wo = np.array([[0.0, np.sin(np.radians(40)), np.cos(np.radians(40))],      # retroreflection
                   [0.0, -np.sin(np.radians(30)), np.cos(np.radians(30))],     # specular side
                   [np.sin(np.radians(10)), 0.0, np.cos(np.radians(10))]])     # 10° out of the plane
    off, signed = geo.plane_offsets(wo, t, n)
    assert np.allclose(off, [0, 0, 10]) and np.allclose(signed[:2], [40, -30])
    # at normal incidence the plane is x–z whatever φi
    assert np.allclose(geo.plane_axes(0.0, 123.0)[0], [1, 0, 0])


def test_cli_plot(dataset, truth_fit, tmp_path, capsys):
    parser = argparse.ArgumentParser(prog="rig")
    plot.add_subcommand(parser.add_subparsers(dest="command", required=True))
    fit_file = tmp_path / "fit.json"
    fit_file.write_text(json.dumps({**truth_fit, "stderr": {}}))
    out = tmp_path / "figs"
    args = parser.parse_args(["plot", str(dataset.path), "--fit", str(fit_file), "--out", str(out)])
    assert args.func(args) == 0 and "11 figures" in capsys.readouterr().err
    assert (out / "fit_residuals.png").exists()
    fit_file.write_text(json.dumps({"dataset": "x", "fits": []}))
    assert args.func(args) == 2 and "not one model's fit" in capsys.readouterr().err
