"""What `rig bench sampling` prints and draws: per draw, as a distribution over draws, and the error–time plot.

Per draw: every strategy's points, rig time (and its ratio to the table's), in-hull median/p95 per region, the
blind pairs, the albedo and road errors, and the verdict: the smallest adaptive budget that reaches the table
(`reached`), or why none did (`why_not`: where the excess lies, how much of it is outside the measured hulls,
how many points were measured near it). Over draws: per budget, the share of draws whose in-hull p95 is no
worse than the table's and the quantiles of p95 / table's p95; the issue's two bars (≥ 80 % of draws by 0.25×,
every draw by 0.5×). The plot: p95 / table's p95 against rig time / table's, a thin line per draw, the median
over draws bold.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rig.bench.distributed import Failure
from rig.bench.sampling import (
    EVERY_DRAW_FRACTION,
    NEAR_DEG,
    OPTIMISED,
    P95_SLACK,
    ROAD_SLACK_REL,
    TABLE,
    TARGET_FRACTION,
    Result,
)

#: The share of draws that must reach the table by TARGET_FRACTION (the issue's bar).
TARGET_SHARE = 0.8


def by_draw(results: Sequence[Result]) -> dict[str, list[Result]]:
    """The results grouped by draw (draw order), each group with its table first and adaptive by budget."""
    groups: dict[str, list[Result]] = {}
    for r in sorted(results, key=lambda r: (int(r.draw.rsplit("#", 1)[1]), r.fraction or -1.0,
                                            r.strategy != TABLE)):
        groups.setdefault(r.draw, []).append(r)
    return groups


def reached(result: Result, table: Result) -> bool:
    """In-hull p95 no worse than the table's (within P95_SLACK). The blind pairs never decide, and neither do R_L
    and Qd: both lie beyond the rig's 85° (every strategy's interpolant extrapolates them), so they compare
    extrapolations, not what was measured; `road_worse` says where they are worse."""
    return result.errors["all_p95"] <= table.errors["all_p95"] + P95_SLACK


def road_worse(result: Result, table: Result) -> list[str]:
    """The road quantities whose error is worse than the table's by more than ROAD_SLACK_REL."""
    e, b = result.errors, table.errors
    return [k.removesuffix("_rel") for k in ("R_L_rel", "Qd_rel")
            if k in b and k in e and abs(e[k]) > abs(b[k]) + ROAD_SLACK_REL]


def table_of(group: Sequence[Result]) -> Result | None:
    return next((r for r in group if r.strategy == TABLE), None)


def adaptive_of(group: Sequence[Result]) -> list[Result]:
    return sorted((r for r in group if r.fraction is not None), key=lambda r: r.rig_time_s)


def smallest_reaching(group: Sequence[Result]) -> Result | None:
    """The adaptive run of least rig time that reaches the table."""
    table = table_of(group)
    return None if table is None else next((r for r in adaptive_of(group) if reached(r, table)), None)


def why_not(group: Sequence[Result]) -> str:
    """Why no adaptive budget reached the table: where the largest budget's excess lies."""
    table, runs = table_of(group), adaptive_of(group)
    assert table is not None and runs
    worst = runs[-1]
    e, b = worst.errors, table.errors
    region = max(("diffuse", "forward", "retro"), key=lambda g: e[f"{g}_p95"] - b[f"{g}_p95"])
    return (f"at {worst.rig_time_s / table.rig_time_s:.2f}× the p95 is {e['all_p95']:.4f} against the table's "
            f"{b['all_p95']:.4f}; the excess is in the {region} region (p95 {e[f'{region}_p95']:.4f} against "
            f"{b[f'{region}_p95']:.4f}); its worst 5 % lie at θi ≈ {worst.worst.theta_i_deg:.0f}°, θo ≈ "
            f"{worst.worst.theta_o_deg:.0f}° (medians), {worst.worst.outside_hull:.0%} of them outside the measured "
            f"views' hulls, with {worst.worst.measured_near} points measured within {NEAR_DEG:g}° of that θi (table: "
            f"{table.worst.outside_hull:.0%} outside, {table.worst.measured_near} points near its worst, at θi ≈ "
            f"{table.worst.theta_i_deg:.0f}°, θo ≈ {table.worst.theta_o_deg:.0f}°)")


def verdict(group: Sequence[Result]) -> str:
    """One line per draw: the smallest budget that reaches the table, as a fraction of its rig time, or why not."""
    table = table_of(group)
    if table is None:
        return f"{group[0].draw}: no table run (failed): nothing to compare with"
    best = smallest_reaching(group)
    if best is None:
        if not adaptive_of(group):
            return f"{table.draw}: no adaptive run finished"
        return f"{table.draw}: table NOT reached within the budgets tried: {why_not(group)}"
    ratio = best.rig_time_s / table.rig_time_s
    worse = road_worse(best, table)
    return (f"{table.draw}: table reached by {best.strategy} in {ratio:.3f}× its rig time "
            f"({'meets' if ratio <= TARGET_FRACTION else 'misses'} the ≤ {TARGET_FRACTION:g}× bar)"
            + (f"; its {' and '.join(worse)} error (extrapolated) is worse than the table's" if worse else ""))


def format_draw(group: Sequence[Result]) -> str:
    """The table of one draw's strategies."""
    table = table_of(group)
    lines = [f"{'draw':18s} {'strategy':17s} {'points':>6s} {'rig min':>7s} {'×table':>6s} {'wall s':>6s} "
             f"{'diffuse med/p95':>16s} {'forward med/p95':>16s} {'retro med/p95':>16s} {'p95':>7s} "
             f"{'blind n/p95':>13s} {'albedo':>7s} {'R_L':>7s} {'Qd':>7s}"]
    for r in group:
        e = r.errors
        ratio = r.rig_time_s / table.rig_time_s if table is not None else np.nan
        lines.append(
            f"{r.draw:18s} {r.strategy:17s} {r.points:6d} {r.rig_time_s / 60:7.1f} {ratio:6.3f} {r.wall_s:6.1f} "
            + " ".join(f"{e[f'{g}_median']:7.4f}/{e[f'{g}_p95']:<8.4f}" for g in ("diffuse", "forward", "retro"))
            + f" {e['all_p95']:7.4f} {e.get('blind_n', 0):5.0f}/{e.get('blind_p95', np.nan):<7.4f}"
              f" {e['albedo_max_rel']:+7.4f} {e.get('R_L_rel', np.nan):+7.4f} {e.get('Qd_rel', np.nan):+7.4f}")
    return "\n".join(lines)


def distribution(results: Sequence[Result], failures: Sequence[Failure] = ()) -> str:
    """Per budget over the draws: reached share, quantiles of rig time and of p95 / table's p95; the bars."""
    groups = {k: g for k, g in by_draw(results).items() if table_of(g) is not None}
    tables = {k: t for k, g in groups.items() if (t := table_of(g)) is not None}
    fractions = sorted({r.fraction for r in results if r.fraction is not None})
    lines = [f"over {len(groups)} draws ({', '.join(sorted({g[0].family for g in groups.values()}))}); "
             f"p95 inside the table's measured domain",
             f"{'strategy':17s} {'draws':>5s} {'×table rig time (median, max)':>30s} {'reached':>8s} "
             f"{'p95/table p95: p10':>18s} {'p50':>6s} {'p90':>6s}"]
    for label in [OPTIMISED] + [f"adaptive ×{f:g}" for f in fractions]:
        rows = [(r, tables[k]) for k, g in groups.items() for r in g if r.strategy == label]
        if not rows:
            continue
        ratio_t = np.array([r.rig_time_s / t.rig_time_s for r, t in rows])
        ratio_e = np.array([r.errors["all_p95"] / t.errors["all_p95"] for r, t in rows])
        share = np.mean([reached(r, t) for r, t in rows])
        q = np.quantile(ratio_e, [0.1, 0.5, 0.9])
        lines.append(f"{label:17s} {len(rows):5d} {np.median(ratio_t):19.3f}, {np.max(ratio_t):8.3f} {share:8.0%} "
                     f"{q[0]:18.3f} {q[1]:6.3f} {q[2]:6.3f}")
    target = {k: smallest_reaching(g) for k, g in groups.items() if adaptive_of(g)}
    ratios = [None if r is None else r.rig_time_s / tables[k].rig_time_s for k, r in target.items()]
    by_target = sum(1 for x in ratios if x is not None and x <= TARGET_FRACTION)
    by_every = sum(1 for x in ratios if x is not None and x <= EVERY_DRAW_FRACTION)
    n = max(len(target), 1)
    lines.append("smallest budget reaching the table (× its rig time), per draw: "
                 + ", ".join("—" if x is None else f"{x:.2f}" for x in ratios))
    lines.append(f"reached by ≤ {TARGET_FRACTION:g}×: {by_target}/{len(target)} draws with an adaptive run "
                 f"({by_target / n:.0%}; bar ≥ {TARGET_SHARE:.0%}: "
                 f"{'met' if by_target / n >= TARGET_SHARE else 'NOT met'}); "
                 f"by ≤ {EVERY_DRAW_FRACTION:g}×: {by_every}/{len(target)} "
                 f"({'every draw' if by_every == len(target) else 'NOT every draw'})")
    if failures:
        lines.append(f"{len(failures)} task(s) FAILED (not counted above):")
        lines += [f"  {f.label}: {f.error}" for f in failures]
    return "\n".join(lines)


def plot(results: Sequence[Result], out_png: Path) -> None:
    """In-hull p95 / table's p95 against rig time / table's: one thin line per draw (adaptive budgets), the
    median over draws bold, the optimised table as points; left absolute, per family colour."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    groups = {k: g for k, g in by_draw(results).items() if table_of(g) is not None}
    families = sorted({g[0].family for g in groups.values()})
    colour = {f: f"C{k}" for k, f in enumerate(families)}
    fig, (left, right) = plt.subplots(1, 2, figsize=(11, 4.2), dpi=110)
    curves: dict[float, list[float]] = {}
    for g in groups.values():
        table = table_of(g)
        assert table is not None
        runs = adaptive_of(g)
        c = colour[g[0].family]
        left.plot([r.rig_time_s / 60 for r in runs], [r.errors["all_p95"] for r in runs], "-", color=c, lw=0.8,
                  alpha=0.7)
        left.plot([table.rig_time_s / 60], [table.errors["all_p95"]], "s", color=c, ms=4)
        x = [r.rig_time_s / table.rig_time_s for r in runs]
        y = [r.errors["all_p95"] / table.errors["all_p95"] for r in runs]
        right.plot(x, y, "-", color=c, lw=0.7, alpha=0.5)
        for r in runs:
            curves.setdefault(float(r.fraction or 0), []).append(r.errors["all_p95"] / table.errors["all_p95"])
        opt = next((r for r in g if r.strategy == OPTIMISED), None)
        if opt is not None:
            right.plot([opt.rig_time_s / table.rig_time_s], [opt.errors["all_p95"] / table.errors["all_p95"]], "D",
                       color=c, ms=3)
    fs = sorted(curves)
    right.plot(fs, [np.median(curves[f]) for f in fs], "k-o", lw=2, label="adaptive, median over draws")
    right.plot([1.0], [1.0], "ks", label="table (paper order, fixed bracket)")
    right.axhline(1.0, color="k", lw=0.6, ls=":")
    right.axvline(TARGET_FRACTION, color="grey", lw=0.6, ls="--")
    for f in families:
        left.plot([], [], "-", color=colour[f], label=f)
    left.set_xlabel("rig time after warm-up, min")
    left.set_ylabel("p95 |ln((f̂+τ)/(f+τ))| in the table's hull")
    left.set_yscale("log")
    left.set_title("per draw: adaptive budgets (lines), table (squares)", fontsize=9)
    right.set_xlabel("rig time / the table's")
    right.set_ylabel("p95 / the table's p95")
    right.set_yscale("log")
    right.set_title("relative to the table (diamonds: table, optimised)", fontsize=9)
    for ax in (left, right):
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out_png)
    plt.close(fig)
