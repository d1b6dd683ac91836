"""The report as one self-contained HTML page: CSS inline, figures as data URIs, no script, no request; every
text taken from a file is escaped. `@media print` starts each section on a new A4 page and keeps figures and
table rows whole, so that a browser's "print to PDF" gives the document to send."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from html import escape

from rig.report.content import Counts, FitSummary, ReportContent, RoadSummary
from rig.report.figures import Embedded, SeriesFigures, illuminance_figure, polar_map

CSS = """
:root { --ink: #1d2733; --muted: #5b6b7c; --rule: #d5dde6; --accent: #1f5f99; --band: #f3f6f9; }
* { box-sizing: border-box; }
body { font: 14px/1.45 "DejaVu Sans", "Helvetica Neue", Arial, sans-serif; color: var(--ink); margin: 0;
       background: #e9edf1; }
main { max-width: 1100px; margin: 24px auto; background: #fff; padding: 36px 48px 28px;
       box-shadow: 0 1px 6px rgba(0,0,0,.12); }
header { border-bottom: 3px solid var(--accent); padding-bottom: 14px; margin-bottom: 8px; }
header .kicker { text-transform: uppercase; letter-spacing: .12em; font-size: 12px; color: var(--accent);
                 font-weight: 600; }
h1 { font-size: 28px; margin: 4px 0 6px; }
header p { margin: 0; color: var(--muted); }
h2 { font-size: 19px; color: var(--accent); border-bottom: 1px solid var(--rule); padding-bottom: 4px;
     margin: 30px 0 12px; }
h3 { font-size: 15px; margin: 18px 0 8px; }
.facts { display: grid; grid-template-columns: repeat(4, 1fr); gap: 10px; margin: 18px 0 4px; }
.fact { background: var(--band); border-left: 3px solid var(--accent); padding: 8px 12px; }
.fact b { display: block; font-size: 20px; }
.fact span { font-size: 12px; color: var(--muted); }
table { border-collapse: collapse; width: 100%; margin: 6px 0 12px; font-size: 13px; }
th, td { text-align: left; padding: 5px 8px; border-bottom: 1px solid var(--rule); vertical-align: top; }
th { background: var(--band); font-weight: 600; }
td.num, th.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
table.compact { width: auto; min-width: 45%; }
table.kv th { width: 32%; background: none; color: var(--muted); font-weight: normal; }
code, .hash { font-family: "DejaVu Sans Mono", Menlo, Consolas, monospace; font-size: 12px; }
.hash, table.kv code { word-break: break-all; }
.two { display: grid; grid-template-columns: 1fr 1fr; gap: 24px; }
figure { margin: 12px 0 18px; text-align: center; }
figure img { max-width: 100%; height: auto; border: 1px solid var(--rule); }
figcaption { font-size: 12px; color: var(--muted); margin-top: 4px; }
.note { font-size: 12px; color: var(--muted); }
.ok { color: #2e7d32; font-weight: 600; } .warn { color: #b23c17; font-weight: 600; }
footer { margin-top: 28px; padding-top: 8px; border-top: 1px solid var(--rule); font-size: 12px; color: var(--muted); }
@page { size: A4; margin: 16mm 14mm 18mm; }
@media print {
  body { background: #fff; font-size: 11px; }
  main { box-shadow: none; margin: 0; padding: 0; max-width: none; }
  section { break-before: page; }
  section.first { break-before: auto; }
  h2, h3 { break-after: avoid; }
  figure, tr, .fact { break-inside: avoid; }
  figure img { max-height: 235mm; }
}
"""


def _e(value: object) -> str:
    return escape(str(value), quote=True)


def sig(value: float | None, digits: int = 4) -> str:
    """A number to `digits` significant digits (– when absent or not finite)."""
    if value is None or not math.isfinite(value):
        return "–"
    return f"{value:.{digits}g}"


def percent(value: float | None, digits: int = 3) -> str:
    return "–" if value is None or not math.isfinite(value) else f"{100 * value:.{digits}g} %"


def with_u(value: float, u: float | None) -> str:
    """value ± u with u to two significant digits and the value to the same decimal place (GUM 7.2.6)."""
    if u is None or not math.isfinite(u) or u <= 0:
        return sig(value, 6)
    decimals = max(0, 1 - math.floor(math.log10(u)))
    return f"{value:.{decimals}f} ± {u:.{decimals}f}" if decimals < 12 else f"{value:.3g} ± {u:.2g}"


def angle(value_deg: float) -> str:
    """An angle in degrees to 0.1°, φ wrapped to [0, 360)."""
    return f"{round(value_deg, 1) % 360:.1f}°"


def table(head: Sequence[str], rows: Iterable[Sequence[str]], numeric: Sequence[int] = (),
          compact: bool = False) -> str:
    """A table of already escaped cells; columns in `numeric` are right-aligned; a compact one is only as wide as
    its cells."""
    cls = [' class="num"' if k in numeric else "" for k in range(len(head))]
    out = [f"<table{' class=compact' if compact else ''}><thead><tr>",
           *(f"<th{c}>{h}</th>" for c, h in zip(cls, head)), "</tr></thead><tbody>"]
    for row in rows:
        out.append("<tr>" + "".join(f"<td{c}>{v}</td>" for c, v in zip(cls, row)) + "</tr>")
    return "".join(out) + "</tbody></table>"


def key_values(rows: Iterable[tuple[str, str]]) -> str:
    """A two-column table of (label, escaped value)."""
    return '<table class="kv"><tbody>' + "".join(f"<tr><th>{_e(k)}</th><td>{v}</td></tr>" for k, v in rows) \
        + "</tbody></table>"


def figure(fig: Embedded | None, caption: str) -> str:
    if fig is None:
        return ""
    return f'<figure><img src="{fig.uri}" alt="{_e(fig.alt)}"><figcaption>{_e(caption)}</figcaption></figure>'


def _section(ident: str, title: str, body: str, first: bool = False) -> str:
    return f'<section id="{ident}"{" class=first" if first else ""}><h2>{_e(title)}</h2>{body}</section>'


def _header(c: ReportContent) -> str:
    facts = [(str(c.counts.measured), "points measured"), (str(len(c.series)), "incidence series"),
             (str(c.counts.skipped), "planned points skipped"),
             ("u not stated" if c.median_u_rel is None else percent(c.median_u_rel, 2),
              "median relative u(f_r), k = 1")]
    cards = "".join(f'<div class="fact"><b>{_e(v)}</b><span>{_e(k)}</span></div>' for v, k in facts)
    return (f'<header><div class="kicker">BRDF measurement report</div><h1>{_e(c.sample_id)}</h1>'
            f"<p>Campaign <b>{_e(c.campaign_name)}</b> on rig <b>{_e(c.rig_name)}</b>"
            f"{' (simulated)' if c.simulated else ''} · status <b>{_e(c.status)}</b> · finished {_e(c.finished_utc)}"
            f'</p><div class="facts">{cards}</div></header>')


def _sample_section(c: ReportContent) -> str:
    hours = None if c.conditions.rig_time_s is None else c.conditions.rig_time_s / 3600
    rows = [("Sample", _e(c.sample_id)), ("Description", _e(c.sample_description or "–")),
            ("Campaign", _e(c.campaign_name)), ("Campaign file", f"<code>{_e(c.campaign_file)}</code>"),
            ("Campaign SHA-256", f'<span class="hash">{_e(c.campaign_sha256)}</span>'),
            ("Status", _e(c.status)), ("Started (UTC)", _e(c.created_utc)), ("Finished (UTC)", _e(c.finished_utc)),
            ("Rig time", f"{sig(hours, 3)} h"),
            ("Software", f"rig {_e(c.software_version)} (measurement), rig {_e(c.report_version)} (this report)")]
    return _section("sample", "Sample and campaign", key_values(rows), first=True)


def _rig_section(c: ReportContent) -> str:
    ids = table(("Device", "Identity"), ((_e(k), _e(v)) for k, v in c.identities.items())) if c.identities \
        else '<p class="note">No device identities recorded (an imported dataset, or the run never connected).</p>'
    body = (f"<p>Rig <b>{_e(c.rig_name)}</b>{' — simulated devices' if c.simulated else ''}.</p>"
            f"<h3>Device identities</h3>{ids}<h3>Calibrations and geometry</h3>"
            + key_values((k, _e(v)) for k, v in c.calibrations))
    if c.filters:
        body += "<h3>Neutral-density filters</h3>" + table(
            ("Position", "Transmission", "u (rel.)"),
            ((_e(f.get("position", "–")), sig(f.get("transmission")), percent(f.get("u_rel"))) for f in c.filters),
            numeric=(0, 1, 2), compact=True)
    return _section("rig", "Rig, devices and calibrations", body)


def _conditions_section(c: ReportContent) -> str:
    k = c.conditions
    trend = k.illuminance
    stable = "–" if k.warmup_stable is None else ('<span class="ok">stable</span>' if k.warmup_stable
                                                   else '<span class="warn">not stable at the maximum</span>')
    warmups = [(run.index, w) for run in k.runs for w in run.warmups]
    rows = [("Lamp warm-up", f"{sig(None if k.warmup_s is None else k.warmup_s / 60, 3)} min, {stable} "
                             f"(last change {percent(k.warmup_change_rel)})")] if len(warmups) < 2 else [
            ("Lamp warm-ups", "; ".join(
                f"run {r + 1} at {sig(w.end_s / 3600, 3)} h: {sig(w.warmup_s / 60, 3)} min, "
                + ('<span class="ok">stable</span>' if w.stable else '<span class="warn">not stable</span>')
                + f" (last change {percent(w.change_rel)})" for r, w in warmups))]
    slopes = trend.run_slopes_rel_per_h()
    rows += [("E⊥ readings", f"{trend.e_perp_lx.size}"),
            ("E⊥ change, first to last reading", percent(trend.change_rel)),
            ("E⊥ trend (least squares within each run)", f"{percent(trend.slope_rel_per_h)} per hour" + (
                " (" + ", ".join(f"run {r + 1}: {percent(x)}" for r, x in enumerate(slopes)) + ")"
                if len(slopes) > 1 else "")),
            ("Pauses by suspenders", str(len(k.pauses))), ("Resumed runs", str(k.resumes))]
    body = key_values(rows) + figure(illuminance_figure(trend), "E⊥ at the sample, relative to its mean, over the run")
    if k.pauses:
        body += "<h3>Pauses</h3>" + table(("Device", "Reason", "Paused"), (
            (_e(p.device), _e(p.reason), "not resumed" if p.waited_s is None else f"{sig(p.waited_s, 3)} s")
            for p in k.pauses))
    survived = {kind: n for kind, n in k.faults.items() if n}
    body += "<h3>Faults survived</h3>" + (table(
        ("Event (events.jsonl)", "Count"), ((f"<code>{_e(kind)}</code>", str(n)) for kind, n in survived.items()),
        numeric=(1,), compact=True) if survived else '<p class="note">None recorded.</p>')
    body += '<p class="note">Counted: ' + ", ".join(f"<code>{_e(kind)}</code>" for kind in k.faults) + ".</p>"
    return _section("conditions", "Conditions", body)


def _counts_section(n: Counts, c: ReportContent) -> str:
    rows = [("Planned", "–" if n.planned is None else str(n.planned)), ("Measured", str(n.measured)),
            ("Skipped by the plan", str(n.skipped)),
            ("Planned but not measured", "–" if n.not_measured is None else str(n.not_measured))]
    body = '<div class="two"><div>' + key_values(rows)
    body += "<h3>Skipped points by reason</h3>" + (table(("Reason", "Points"), (
        (f"<code>{_e(r)}</code>", str(v)) for r, v in n.skipped_by_reason.items()), numeric=(1,))
        if n.skipped_by_reason else '<p class="note">None.</p>')
    body += "</div><div><h3>Incidence series</h3>" + table(("Series", "θi", "φi", "Points"), (
        (str(s.index), angle(s.theta_i_deg), angle(s.phi_i_deg), str(s.points)) for s in c.series),
        numeric=(0, 1, 2, 3))
    body += "<h3>Quality flags</h3>" + (table(("Flag", "Points"), (
        (f"<code>{_e(f)}</code>", str(v)) for f, v in n.flagged.items()), numeric=(1,))
        if n.flagged else '<p class="note">No point flagged.</p>')
    return _section("counts", "Points measured and skipped", body + "</div></div>")


def _budget_section(c: ReportContent) -> str:
    if not c.budget:
        return _section("budget", "Uncertainty budget", '<p class="note">The dataset has no uncertainty components '
                                                         "(u_rel_* columns), e.g. an imported one.</p>")
    body = table(("Component", "Meaning", "Median u", "95th percentile u", "Median share of u²"), (
        (f"<code>{_e(b.component)}</code>", _e(b.meaning), percent(b.median_u_rel), percent(b.p95_u_rel),
         percent(b.median_share)) for b in c.budget), numeric=(2, 3, 4))
    note = ('<p class="note">Relative standard uncertainties (k = 1) of f_r over the measured points; the components '
            "combine in quadrature to u(f_r)/f_r (docs/dataset.md).</p>")
    return _section("budget", "Uncertainty budget", note + body)


def _figures_section(c: ReportContent, figs: SeriesFigures) -> str:
    body = figure(polar_map(c.dataset), "Where each series looked: every measured view, colour = f_r")
    for s in c.series:
        label = f"series {s.index}: θi {angle(s.theta_i_deg)}, φi {angle(s.phi_i_deg)}"
        body += f"<h3>Series {s.index} — θi {angle(s.theta_i_deg)}, φi {angle(s.phi_i_deg)}</h3>"
        body += figure(figs.plane.get(s.index), f"f_r in the plane of incidence, {label}")
        body += figure(figs.lobe.get(s.index), f"BRDF lobe, {label}")
    return _section("figures", "Figures", body)


def _fit_section(fit: FitSummary, figs: SeriesFigures) -> str:
    params = table(("Parameter", "Value ± u (k = 1)", "u (rel.)"), (
        (_e(p.name), with_u(p.value, p.stderr),
         percent(None if p.stderr is None or p.value == 0 else p.stderr / abs(p.value), 2)) for p in fit.parameters),
        numeric=(1, 2))
    m, d = fit.metrics, fit.diagnostics
    metrics = [("RMSE", f"{sig(m.get('rmse'))} sr⁻¹"), ("NRMSE", sig(m.get("nrmse"))), ("NCC", sig(m.get("ncc"), 6)),
               ("Points fitted", _e(d.get("n_points", "–"))), ("Weighting", _e(d.get("weighting", "–"))),
               ("χ²/dof", sig(d["chi2_dof"] if isinstance(d.get("chi2_dof"), float) else None, 3)),
               ("Converged", _e(d.get("converged", "–")))]
    body = (f"<p>Model <b>{_e(fit.model)}</b>, as fitted by <code>rig fit --json</code>.</p>"
            f'<div class="two"><div>{params}</div><div>{key_values(metrics)}</div></div>')
    return _section("fit", "Model fit", body + figure(figs.residuals, "fitted against measured f_r, and residuals"))


def _road_section(road: RoadSummary) -> str:
    body = table(("Quantity", "Value ± u (k = 1)", "Unit"), (
        (_e(q.name), with_u(q.value, q.u), _e(q.unit)) for q in road.quantities), numeric=(1,), compact=True)
    if road.classes:
        body += "<h3>Classes</h3>" + key_values((k, _e(v)) for k, v in road.classes.items())
    body += "".join(f'<p class="note"><b>{_e(k)}:</b> {_e(v)}</p>' for k, v in road.notes)
    return _section("road", "Road-lighting quantities", body)


def render(c: ReportContent, figs: SeriesFigures) -> str:
    """The whole HTML document."""
    parts = [_header(c), _sample_section(c), _rig_section(c), _conditions_section(c), _counts_section(c.counts, c),
             _budget_section(c), _figures_section(c, figs)]
    if c.fit is not None:
        parts.append(_fit_section(c.fit, figs))
    if c.road is not None:
        parts.append(_road_section(c.road))
    footer = (f"<footer>Written by rig {_e(c.report_version)} from the dataset written by rig "
              f"{_e(c.software_version)}; campaign SHA-256 <span class=hash>{_e(c.campaign_sha256)}</span>.</footer>")
    return ('<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
            '<meta name="viewport" content="width=device-width, initial-scale=1">'
            f"<title>BRDF report — {_e(c.sample_id)}</title><style>{CSS}</style></head>"
            f"<body><main>{''.join(parts)}{footer}</main></body></html>\n")
