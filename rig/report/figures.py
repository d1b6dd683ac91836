"""The report's figures as PNG data URIs, so that the HTML file carries them and requests nothing.

The plane-of-incidence, lobe and residual figures are `rig plot`'s own (rig.analysis.plots.plot_dataset, drawn
into a temporary folder and read back); the polar map of every view and the E⊥ trend are drawn here.
"""

from __future__ import annotations

import base64
import io
import re
import tempfile
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import cast

import numpy as np
from matplotlib.colors import LogNorm, Normalize
from matplotlib.figure import Figure
from matplotlib.layout_engine import ConstrainedLayoutEngine
from matplotlib.projections.polar import PolarAxes

from rig.analysis.plots import DPI, MEASURED, plot_dataset
from rig.data.dataset_reader import Dataset
from rig.report.content import IlluminanceTrend

#: rig plot's file names: kind, series and incidence θi, φi (rig.analysis.plots.series_stem).
PLOT_NAME = re.compile(r"(?P<kind>plane|lobe)_s(?P<series>\d+)_ti\d+_pi\d+\.png")
#: Polar panels per row in the map of all views.
POLAR_COLUMNS = 3


@dataclass(frozen=True)
class Embedded:
    """One figure ready for an <img>: its data URI and the text a reader without images gets."""
    uri: str
    alt: str


def png_uri(data: bytes) -> str:
    return "data:image/png;base64," + base64.b64encode(data).decode("ascii")


def _figure_uri(fig: Figure) -> str:
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI, bbox_inches="tight")
    return png_uri(buffer.getvalue())


@dataclass(frozen=True)
class SeriesFigures:
    plane: dict[int, Embedded]
    lobe: dict[int, Embedded]
    residuals: Embedded | None


def series_figures(ds: Dataset, fit: Mapping | None) -> SeriesFigures:
    """rig plot's figures of every series (with the fitted model drawn in when a fit is given)."""
    plane: dict[int, Embedded] = {}
    lobe: dict[int, Embedded] = {}
    residuals = None
    with tempfile.TemporaryDirectory(prefix="rig-report-") as tmp:
        for path in plot_dataset(ds, Path(tmp) / "figures", fit):
            uri = png_uri(path.read_bytes())
            match = PLOT_NAME.fullmatch(path.name)
            if match is None:
                residuals = Embedded(uri, "fitted against measured f_r and relative residuals")
            else:
                s = int(match["series"])
                target = plane if match["kind"] == "plane" else lobe
                target[s] = Embedded(uri, f"{match['kind']} figure of series {s}")
    return SeriesFigures(plane, lobe, residuals)


def polar_map_figure(ds: Dataset) -> Figure:
    """Every measured view of each series on a polar map (angle φo, radius θo), colour = f_r (log where all are
    positive): where the campaign looked, and where the lobes are. Laid out by matplotlib's constrained layout, so
    that a panel's azimuth labels keep clear of its neighbour's; azimuth labels every 90° and radial ones at 30° and
    60° only (the rim is the horizon), so that no "90°" names both θo and φo."""
    series = np.unique(ds["series"]).astype(int)
    rows = int(np.ceil(len(series) / POLAR_COLUMNS))
    f = ds["brdf_per_sr"]
    norm = LogNorm(f.min(), f.max()) if f.size and np.all(f > 0) else Normalize(f.min(), f.max())
    fig = Figure(figsize=(3.4 * POLAR_COLUMNS + 1.2, 3.3 * rows + 0.6),
                 layout=ConstrainedLayoutEngine(w_pad=0.12, h_pad=0.1, wspace=0.08, hspace=0.06))
    axes = [cast(PolarAxes, fig.add_subplot(rows, POLAR_COLUMNS, k + 1, projection="polar"))
            for k in range(len(series))]
    dots = None
    for ax, s in zip(axes, series.tolist()):
        keep = ds["series"] == s
        theta_i, phi_i = ds.series_incidence_deg(s)
        dots = ax.scatter(np.radians(ds["phi_o_deg"][keep]), ds["theta_o_deg"][keep], c=f[keep], norm=norm,
                          cmap="viridis", s=16, edgecolors="k", linewidths=0.3)
        ax.plot([np.radians(phi_i)], [theta_i], marker="*", ms=13, color="#ff7f0e", mec="k", mew=0.5, ls="none")
        ax.set_ylim(0, 90)
        ax.set_rlabel_position(135)        # radial labels between the azimuth labels, away from 0° (the lamp side)
        ax.set_yticks([30, 60, 90], ["30°", "60°", ""], fontsize=8, color="0.3")
        ax.set_xticks(np.radians([0, 90, 180, 270]), ["0°", "90°", "180°", "270°"], fontsize=9)
        ax.tick_params(axis="x", pad=1)
        ax.set_title(f"series {s}: θi {theta_i:.1f}°, φi {round(phi_i, 1) % 360:.1f}°", fontsize=10)
    if dots is not None:
        fig.colorbar(dots, ax=axes, shrink=0.9 if rows < 3 else 0.45, aspect=25, label="f_r [sr⁻¹]")
    fig.suptitle("Measured views: angle φo, radius θo (rings at 30° and 60°, rim at 90°); "
                 "★ the lamp's direction (θi, φi)", fontsize=11)
    return fig


def polar_map(ds: Dataset) -> Embedded:
    """The polar map of `polar_map_figure`, embedded."""
    return Embedded(_figure_uri(polar_map_figure(ds)), "polar map of the measured views of every series")


def illuminance_figure(trend: IlluminanceTrend) -> Embedded | None:
    """E⊥ readings (± u) against rig time, in hours, relative to their mean: the lamp's drift at a glance."""
    if trend.rig_time_s.size == 0:
        return None
    mean = float(np.mean(trend.e_perp_lx))
    t_h = trend.rig_time_s / 3600.0
    fig = Figure(figsize=(7.5, 2.6))
    ax = fig.add_subplot()
    runs = trend.runs()                 # each run its own line: none is drawn across a resume
    for r, k in enumerate(runs):
        ax.errorbar(t_h[k], 100 * (trend.e_perp_lx[k] / mean - 1), yerr=100 * trend.u_lx[k] / mean, fmt="o-", ms=4,
                    color=MEASURED if r == 0 else f"C{r + 1}", ecolor="0.5", capsize=2, lw=1,
                    label=f"run {r + 1}" if len(runs) > 1 else None)
    if len(runs) > 1:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    ax.axhline(0, color="0.4", lw=0.8)
    ax.set(xlabel="rig time [h]", ylabel="E⊥ / mean − 1 [%]", title=f"E⊥ readings (mean {mean:.5g} lx, ± u)")
    ax.grid(True, alpha=0.3)
    return Embedded(_figure_uri(fig), "E⊥ readings against rig time")
