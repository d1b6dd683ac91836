"""Figures that read at a glance (issue 35, item 4): every figure kind of `rig plot` and `rig report` is drawn, and
its texts are checked where matplotlib placed them (bounding boxes from `get_window_extent` after a draw): no tick
label of one polar panel over its neighbour's, no axis title over tick labels in the 3D lobe, the residual figure's
keys outside its data and its series told apart by colour and marker, legible font sizes. (File names with θi and φi:
tests/analysis/test_plots.py.)
"""

from dataclasses import replace
from itertools import combinations

import numpy as np
import pytest
from matplotlib import rc_context
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.text import Text
from matplotlib.transforms import Bbox

from rig.analysis import plots
from rig.report.figures import polar_map_figure

#: The smallest font (points) a figure may use for a text a reader needs.
MIN_FONT_PT = 7.5


@pytest.fixture(scope="module")
def truth_fit(e2e_dataset):
    truth = e2e_dataset.manifest["simulated_brdf"]
    return {"model": truth["model"], "params": truth["params"], "metrics": {"rmse": 0.0}}


class Drawn:
    """A figure drawn on an Agg canvas, with the window extent of every text as it was drawn (asked afterwards, a
    3D axis's tick label has been moved back to its data position by `get_ticklabels`)."""

    def __init__(self, fig: Figure):
        self.extent: dict[int, Bbox] = {}
        original = Text.draw

        def draw(text: Text, renderer) -> None:
            original(text, renderer)
            if text.get_visible() and text.get_text().strip():
                self.extent[id(text)] = text.get_window_extent(renderer)

        canvas = FigureCanvasAgg(fig)
        Text.draw = draw                    # type: ignore[method-assign]
        try:
            canvas.draw()
        finally:
            Text.draw = original            # type: ignore[method-assign]
        self.renderer = canvas.get_renderer()

    def boxes(self, texts) -> list[Bbox]:
        """Extents of those of `texts` that were drawn."""
        return [self.extent[id(t)] for t in texts if id(t) in self.extent]


def ticks(axis) -> list[Text]:
    """An axis's tick labels without re-placing them (`Axis.get_ticklabels` would)."""
    return [t.label1 for t in axis.majorTicks] + [t.label2 for t in axis.majorTicks]


def overlapping(a: list[Bbox], b: list[Bbox]) -> list[tuple[Bbox, Bbox]]:
    return [(p, q) for p in a for q in b if p.overlaps(q)]


def tick_labels(ax) -> list[Text]:
    return ticks(ax.xaxis) + ticks(ax.yaxis)


def test_polar_map_panels_keep_their_labels_apart(e2e_dataset):
    """Five series in rows of three: no azimuth or radial label of one panel meets one of another panel, and within
    a panel no radial label meets an azimuth label (the old layout put "180°" over the neighbour's "0°")."""
    fig = polar_map_figure(e2e_dataset)
    d = Drawn(fig)
    panels = [ax for ax in fig.axes if ax.name == "polar"]
    assert len(panels) == 5
    for a, b in combinations(panels, 2):
        assert not overlapping(d.boxes(tick_labels(a)), d.boxes(tick_labels(b))), (a.get_title(), b.get_title())
        assert not a.get_tightbbox(d.renderer).overlaps(b.get_tightbbox(d.renderer))
    for ax in panels:
        assert len(d.boxes(ticks(ax.xaxis))) == 4 and len(d.boxes(ticks(ax.yaxis))) == 2
        assert not overlapping(d.boxes(ticks(ax.xaxis)), d.boxes(ticks(ax.yaxis)))
        labels = [t.get_text() for t in tick_labels(ax) if id(t) in d.extent]
        assert len(labels) == len(set(labels)), labels          # no "90°" for both θo and φo
        assert min(t.get_fontsize() for t in tick_labels(ax)) >= MIN_FONT_PT


def test_lobe_axis_titles_clear_of_tick_labels(e2e_dataset, truth_fit):
    """The 3D lobe at every incidence of the e2e campaign: an axis title meets no tick label, no tick label meets
    another (of its axis or of another axis: the old view along the plane piled the y and z ticks at one corner),
    the legend and colour bar do not meet the axes' titles."""
    for series in range(5):
        fig = plots.lobe_figure(e2e_dataset, series, plots._record_model(truth_fit))
        d = Drawn(fig)
        ax = fig.axes[0]
        titles = d.boxes([ax.xaxis.label, ax.yaxis.label, ax.zaxis.label])
        labels = [d.boxes(ticks(axis)) for axis in (ax.xaxis, ax.yaxis, ax.zaxis)]
        assert len(titles) == 3 and all(len(t) >= 2 for t in labels), [len(t) for t in labels]
        assert not overlapping(titles, [b for t in labels for b in t]), series
        for t in labels:
            assert not [(p, q) for p, q in combinations(t, 2) if p.overlaps(q)], series
        for a, b in combinations(labels, 2):
            assert not overlapping(a, b), series
        keys = d.boxes(fig.legends[0].get_texts()) + [fig.axes[1].get_tightbbox(d.renderer)]
        assert not overlapping(keys, titles), series


def test_plane_legends_beside_the_data(e2e_dataset, truth_fit):
    """The plane figure at every incidence: its two legends and the colour bar meet neither panel, and no text is
    smaller than MIN_FONT_PT."""
    for series in range(5):
        with rc_context({"font.size": plots.PLANE_FONT_PT}):
            fig = plots.plane_figure(e2e_dataset, series, plots._record_model(truth_fit))
            d = Drawn(fig)
        polar, cartesian = fig.axes[:2]
        legends = [fig.legends[0], cartesian.get_legend()]
        panels = [polar.patch.get_window_extent(d.renderer), cartesian.get_window_extent(d.renderer)]   # the half disk
        assert not overlapping([lg.get_window_extent(d.renderer) for lg in legends], panels), series
        assert not overlapping([fig.axes[2].get_window_extent(d.renderer)], panels[:1]), series
        texts = [t for lg in legends for t in lg.get_texts()] + tick_labels(cartesian)
        assert min(t.get_fontsize() for t in texts if id(t) in d.extent) >= MIN_FONT_PT


def test_residual_keys_outside_the_data_and_series_apart(paper_like, truth_fit):
    """Sixteen series (the paper's incidences at three φi): the marker legend and the colour bar lie outside both
    panels; each series' colour follows θi and its marker φi, so no two series look alike."""
    fig = plots.residual_figure(paper_like, truth_fit)
    renderer = Drawn(fig).renderer
    panels = fig.axes[:2]
    keys = [fig.legends[0].get_window_extent(renderer), fig.axes[2].get_window_extent(renderer)]
    for ax in panels:
        assert not ax.get_legend()
        assert not [k for k in keys if k.overlaps(ax.get_window_extent(renderer))]
    looks = {(tuple(np.round(c.get_facecolors()[0], 3)), np.round(c.get_paths()[0].vertices, 3).tobytes())
             for c in panels[1].collections if len(c.get_facecolors()) == 1}          # the series' scatters
    assert len(looks) == 16
    assert min(t.get_fontsize() for t in fig.legends[0].get_texts()) >= MIN_FONT_PT


@pytest.fixture(scope="module")
def paper_like(e2e_dataset):
    """The e2e dataset relabelled into sixteen series (θi from the paper's Table 1 at φi 0°, 23°, 45°): the
    residual figure's legend problem needs many series, not a long campaign."""
    incidences = [(t, 0.0) for t in (0, 10, 20, 30, 40, 50, 60, 70, 80, 85)] + [
        (t, p) for p in (23.0, 45.0) for t in (70, 80, 85)]
    columns = {k: np.array(v, copy=True) for k, v in e2e_dataset.columns.items()}
    n = len(columns["series"])
    series = np.arange(n) % len(incidences)
    columns["series"] = series.astype(float)
    columns["theta_i_deg"] = np.array([incidences[s][0] for s in series], float)
    columns["phi_i_deg"] = np.array([incidences[s][1] for s in series], float)
    return replace(e2e_dataset, columns=columns)


def test_residual_tick_labels_stay_apart_on_a_narrow_log_range(e2e_dataset, truth_fit):
    """A sample whose f_r spans less than a decade (0.2–0.6 sr⁻¹): matplotlib then labels the log axis's minor
    ticks, and "3×10⁻¹" ran into "4×10⁻¹". No two drawn tick labels of either log axis may overlap."""
    columns = {k: np.array(v, copy=True) for k, v in e2e_dataset.columns.items()}
    f = columns["brdf_per_sr"]
    columns["brdf_per_sr"] = 0.2 + 0.4 * (f - f.min()) / np.ptp(f)
    narrow = replace(e2e_dataset, columns=columns)
    fig = plots.residual_figure(narrow, truth_fit)
    drawn = Drawn(fig)
    ax_fit = fig.axes[0]
    for axis in (ax_fit.xaxis, ax_fit.yaxis):
        labels = drawn.boxes(t.label1 for t in axis.majorTicks + axis.minorTicks)
        assert len(labels) >= 2                                  # the axis is still labelled
        assert not [(p, q) for p, q in combinations(labels, 2) if p.overlaps(q)]
