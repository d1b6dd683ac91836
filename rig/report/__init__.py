"""`rig report`: a dataset's measurement report as one self-contained HTML file (docs/report.md): the facts
(rig.report.content), the figures (rig.report.figures) and the page (rig.report.html).

Entry points: `report_html` (below), `rig report` (rig.cli.report).
May import: rig.session and every layer below it (it reads datasets with rig.data and fits with
rig.analysis); not rig.monitor or rig.bench beside it, nor rig.cli.
"""

from __future__ import annotations

from collections.abc import Mapping

from rig.data.dataset_reader import Dataset
from rig.report.content import collect
from rig.report.figures import series_figures
from rig.report.html import render


def report_html(ds: Dataset, fit: Mapping | None = None, road: Mapping | None = None) -> str:
    """The report of a loaded dataset, with a fit record (`rig fit --json`) and road.json (`rig export --format
    road`) when given."""
    return render(collect(ds, fit, road), series_figures(ds, fit))
