"""`rig plan`'s estimate against the simulated run's rig time, warm-up included (issue 35), for the shipped
campaigns: `python benchmarks/plan_estimate.py [campaign.yaml ...]` (default quick and the paper's RM1). Prints
the planned and the measured rig time, and the warm-up expected and taken."""

from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

from rig.acquisition.progress import format_duration
from rig.cli.main import main
from rig.config.campaign import load_campaign
from rig.config.rigfile import simulated_rig
from rig.planning.estimate import NOMINAL_CAPTURE_S
from rig.planning.plan import build_plan, estimate_rig_time_s
from rig.session.warmup_estimate import expected_warmup

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = [ROOT / "campaigns" / "quick.yaml", ROOT / "campaigns" / "spieringhs2023-rm1.yaml"]


def compare(path: Path) -> None:
    campaign, rig = load_campaign(path), simulated_rig()
    warm = expected_warmup(campaign, rig)
    planned = rig.lamp.ramp_s + warm.seconds + estimate_rig_time_s(build_plan(campaign, rig), rig.axes,
                                                                   NOMINAL_CAPTURE_S)
    with tempfile.TemporaryDirectory() as tmp:
        wall = time.perf_counter()
        assert main(["run", str(path), "--out", f"{tmp}/ds", "--quiet"]) == 0
        wall = time.perf_counter() - wall
        manifest = json.loads(Path(f"{tmp}/ds/dataset.json").read_text())
    taken = manifest["rig_time_s"]
    warmup = manifest["runs"][0]["warmups"][0]["warmup_s"]
    print(f"{path.name}: planned {format_duration(planned)}, run {format_duration(taken)} "
          f"({planned / taken - 1:+.1%}); warm-up expected {warm.seconds:.0f} s, taken {warmup:.0f} s; "
          f"run's wall time {wall:.0f} s")


if __name__ == "__main__":
    for name in sys.argv[1:] or DEFAULT:
        compare(Path(name))
