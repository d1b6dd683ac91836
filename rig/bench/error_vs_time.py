"""BRDF error against rig time for several capture settings.

Runs one campaign on the simulated rig once per capture setting (the same plan,
the same simulated sample) and compares each dataset with the simulated truth
at the achieved angles: median and 95th-percentile relative error, and how often
|f − f_true| ≤ 2u (k = 2 coverage of the reported uncertainty). Rig time is the
simulated clock (total, and the part spent capturing); wall time is this
machine's. The fixed 5-exposure bracket is the baseline the others are
compared with, as ratios.
"""

from __future__ import annotations

import os
import platform
import tempfile
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from rig.acquisition.run import run_campaign
from rig.config.campaign import Campaign
from rig.config.rigfile import RigConfig
from rig.data.dataset_reader import load
from rig.physics.brdf_models import get_model
from rig.session.connect import open_campaign_rig

BASELINE = "fixed bracket 5×1 stop"
SETTINGS: dict[str, dict[str, Any]] = {
    BASELINE: {"mode": "fixed_bracket"},
    "adaptive (defaults)": {"mode": "adaptive"},
    "adaptive, peak at 20 %": {"mode": "adaptive", "target_fraction": 0.2},
    "adaptive, SNR 20000": {"mode": "adaptive", "target_snr": 20000},
    "adaptive, 4 frames": {"mode": "adaptive", "frames_per_exposure": 4},
}


def dataset_errors(folder: Path) -> dict[str, float]:
    """Errors of a simulated dataset against the truth in its manifest."""
    d = load(folder)
    truth_spec = d.manifest["simulated_brdf"]
    wi, wo = d.directions()
    truth = get_model(truth_spec["model"])(wi, wo, truth_spec["params"])
    f, u = d["brdf_per_sr"], d["u_brdf_per_sr"]
    rel = np.abs(f - truth) / truth
    return {"n": len(d), "median_rel_error": float(np.median(rel)), "p95_rel_error": float(np.percentile(rel, 95)),
            "coverage_k2": float(np.mean(np.abs(f - truth) <= 2 * u)),
            "capture_time_s": float(np.sum(d["capture_time_s"])),
            "finite": bool(np.all(np.isfinite(f)) and np.all(np.isfinite(u)))}


def run_settings(campaign: Campaign, campaign_path: Path, settings: Mapping[str, Mapping[str, Any]],
                 rig: RigConfig | None = None) -> list[dict]:
    """Run the campaign once per capture setting (default: on the built-in simulated rig); a row per setting."""
    rig = rig or RigConfig()
    results = []
    for label, overrides in settings.items():
        variant = campaign.model_copy(update={"capture": campaign.capture.model_copy(update=dict(overrides))})
        with tempfile.TemporaryDirectory() as tmp:
            outcome = run_campaign(variant, rig, Path(tmp) / "ds", open_campaign_rig, campaign_file=campaign_path)
            if outcome.status != "complete":
                raise RuntimeError(f"setting {label!r}: campaign {outcome.status}: {outcome.error}")
            results.append({"setting": label, "rig_time_s": outcome.rig_time_s, "wall_s": outcome.wall_s,
                            **dataset_errors(Path(tmp) / "ds")})
    return results


def best_of(fn: Callable[[], object], repeat: int) -> float:
    """Shortest wall time (s) of `repeat` calls: the least disturbed by other processes."""
    walls = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        walls.append(time.perf_counter() - start)
    return min(walls)


def machine() -> str:
    """What benchmark figures were measured on: host, CPU model, cores, Python, numpy, OS."""
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return (f"{platform.node()} | {cpu} | {os.cpu_count()} cores | Python {platform.python_version()} | "
            f"numpy {np.__version__} | {platform.platform()}")


def format_table(results: Sequence[dict], campaign: str) -> str:
    base = next((r for r in results if r["setting"] == BASELINE), results[0])
    lines = [f"machine : {machine()}",
             f"campaign: {campaign}; simulated rig; {base['n']} points per setting",
             f"{'setting':28s} {'rig h':>6s} {'capture s':>9s} {'×base':>6s} {'wall s':>7s} "
             f"{'median %':>8s} {'p95 %':>6s} {'k=2 cov':>7s}"]
    for r in results:
        lines.append(f"{r['setting']:28s} {r['rig_time_s'] / 3600:6.3f} {r['capture_time_s']:9.1f} "
                     f"{r['capture_time_s'] / base['capture_time_s']:6.2f} {r['wall_s']:7.1f} "
                     f"{100 * r['median_rel_error']:8.3f} {100 * r['p95_rel_error']:6.3f} {r['coverage_k2']:7.3f}")
    matching = [r for r in results if r["setting"] != BASELINE
                and r["median_rel_error"] <= base["median_rel_error"] * 1.05]
    if matching and base["setting"] == BASELINE:
        best = min(matching, key=lambda r: r["capture_time_s"])
        lines.append(f"fastest setting within 5 % of the baseline's median error: {best['setting']}: "
                     f"{best['capture_time_s'] / base['capture_time_s']:.2f}× the baseline's capture rig time, "
                     f"{best['rig_time_s'] / base['rig_time_s']:.2f}× its total rig time (moves included)")
    return "\n".join(lines)


def plot(results: Sequence[dict], out_png: Path, title: str) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4.5), dpi=120)
    for r in results:
        x = r["capture_time_s"] / 60
        ax.scatter([x], [100 * r["median_rel_error"]], marker="o", color="C0")
        ax.scatter([x], [100 * r["p95_rel_error"]], marker="^", color="C1")
        ax.annotate(r["setting"], (x, 100 * r["median_rel_error"]), textcoords="offset points", xytext=(4, -10),
                    fontsize=7)
    ax.scatter([], [], marker="o", color="C0", label="median |relative error|")
    ax.scatter([], [], marker="^", color="C1", label="95th percentile")
    ax.set_xlabel("rig time spent capturing (simulated), min")
    ax.set_ylabel("BRDF error vs simulated truth, %")
    ax.set_title(title, fontsize=10)
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_png)
    plt.close(fig)
