"""The road quantities of road.json (rig.analysis.road) as road-lighting designers take them: a DIALux r-table
file (`.RTB`) and a summary on the terminal.

DIALux `.RTB` (DIAL support article 9000073306, "R-tables in DIALux", DIALux ≥ 4.6): plain text, one item per
line, no comments:

    RTable.v1            the format's tag ("should not be modified")
    <name>               the surface's name, shown in DIALux
    <nEps>               the number of tan ε values (29 for the standard grid)
    tan ε …              nEps lines
    <nBeta>              the number of β values (20)
    β …                  nBeta lines, degrees
    q0                   the average luminance coefficient Q0 (sr⁻¹)
    r …                  nEps × nBeta lines, tan ε varying fastest: r(ε1, β1), r(ε2, β1), …, r(εn, βm)

ε is the article's name for the incidence angle that rig.analysis.road calls γ. The article does not say in
which unit r is listed; the tables of EN 13201-3 and CIE 144 that its layout follows list r × 10⁴, as road.json
does (`r_x1e4`), so the file holds road.json's numbers unchanged: its grids, its `r_x1e4` and its `Q0`, each
written with Python's shortest round-trip repr (the file reads back equal to road.json). An r-table has no
place for an undefined value: a road.json quantity that is null (not finite) is refused, naming it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from rig.data.output_folder import new_file

RTB_TAG = "RTable.v1"


class RtbError(ValueError):
    """The r-table cannot be written as an .RTB; the message says which value and why."""


def _number(value: Any, what: str) -> float:
    if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
        raise RtbError(f"{what} is {value!r}, not a finite number: an .RTB has no place for an undefined value "
                       "(see road.json's 'undefined')")
    return float(value)


def rtb_lines(document: Mapping[str, Any], name: str) -> list[str]:
    """The lines of the .RTB of a road.json document (rig.analysis.road.road_json), in the article's order."""
    table = document["r_table"]
    tan_eps = [_number(v, f"r_table.tan_gamma[{i}]") for i, v in enumerate(table["tan_gamma"])]
    beta = [_number(v, f"r_table.beta_deg[{j}]") for j, v in enumerate(table["beta_deg"])]
    rows = table["r_x1e4"]                              # [tan γ][β]
    if len(rows) != len(tan_eps) or any(len(row) != len(beta) for row in rows):
        raise RtbError(f"r_table.r_x1e4 is not {len(tan_eps)} rows of {len(beta)} values")
    r = [_number(rows[i][j], f"r_table.r_x1e4[{i}][{j}] (tan γ {tan_eps[i]:g}, β {beta[j]:g}°)")
         for j in range(len(beta)) for i in range(len(tan_eps))]          # tan ε varying fastest
    label = " ".join(name.split()) or "rig r-table"     # one line: DIALux reads the name as line 2
    return [RTB_TAG, label, str(len(tan_eps)), *map(repr, tan_eps), str(len(beta)), *map(repr, beta),
            repr(_number(document["Q0"], "Q0")), *map(repr, r)]


def write_rtb(document: Mapping[str, Any], out: Path, name: str) -> Path:
    """Write the .RTB under a temporary name, named when complete (never over an existing file)."""
    text = "\r\n".join(rtb_lines(document, name)) + "\r\n"     # a Windows program's text file
    with new_file(Path(out)) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(out)


def _value(document: Mapping[str, Any], key: str, unit: str) -> str:
    value, u = document.get(key), document.get(f"u_{key}")
    if value is None:
        return "undefined"
    return f"{value:.4g} ± {u:.2g} {unit}" if u is not None else f"{value:.4g} {unit} (u undefined)"


def _classes(cls: str | None, within: Sequence[str]) -> str:
    span = "–".join(dict.fromkeys([within[0], within[-1]])) if within else "none"
    return f"class {cls or 'undefined'} (k = 2 range: {span})"


def road_summary(document: Mapping[str, Any]) -> list[str]:
    """Lines for the terminal: R_L, Qd, Q0, S1 with their u (k = 1) and the classes each reaches at k = 2."""
    marking, marking_k2 = document["marking_classes"], document["marking_classes_within_k2"]
    surface, surface_k2 = document["surface_classes"], document["surface_classes_within_k2"]
    return [
        f"R_L = {_value(document, 'R_L_mcd_m2_lx', 'mcd·m⁻²·lx⁻¹')}, "
        f"{_classes(marking['R_L'], marking_k2['R_L'])}",
        f"Qd  = {_value(document, 'Qd_mcd_m2_lx', 'mcd·m⁻²·lx⁻¹')}, {_classes(marking['Qd'], marking_k2['Qd'])}",
        f"Q0  = {_value(document, 'Q0', 'sr⁻¹')}",
        f"S1  = {_value(document, 'S1', '')}".rstrip() + ", "
        + "; ".join(f"{family}: {_classes(surface[family], surface_k2[family])}" for family in surface),
        "u at k = 1; where these rest on the predictor's extrapolation: road.json's 'extrapolated'",
    ]
