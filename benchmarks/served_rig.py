"""Served-rig benchmark: campaigns run by `rig run --rig` against `rig sim serve` in another process,
compared with the same campaigns on the in-process simulated rig of the same run.

Prints the machine, the settings, and per campaign: status, points, rig time and wall time of both,
and how the served run's rig time compares (the served world runs on a wall clock `--speed` times
faster than wall time, so the client's computing time counts as rig time there, and not in-process).

    python benchmarks/served_rig.py [--speed N] [CAMPAIGN ...]
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.bench.error_vs_time import machine  # noqa: E402

CAMPAIGNS = [ROOT / "campaigns" / "quick.yaml", ROOT / "campaigns" / "spieringhs2023-rm1.yaml"]


def rig(*args: str) -> list[str]:
    return [sys.executable, "-m", "rig.cli.main", *args]


def run(campaign: Path, out: Path, *extra: str) -> tuple[dict, float]:
    """`rig run` to completion; (the manifest, wall seconds)."""
    t0 = time.perf_counter()
    done = subprocess.run(rig("run", str(campaign), "--out", str(out), "--quiet", *extra), capture_output=True,
                          text=True)
    wall = time.perf_counter() - t0
    if done.returncode != 0:
        print(done.stderr, file=sys.stderr)
    return json.loads((out / "dataset.json").read_text()), wall


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("campaigns", nargs="*", type=Path, default=CAMPAIGNS)
    ap.add_argument("--speed", type=float, default=50.0, help="rig seconds per wall second of the served world")
    args = ap.parse_args()
    print(f"machine : {machine()}")
    print(f"settings: served at {args.speed:g}× wall time, lamp watchdog 10 s; one server per campaign "
          "(its sample is the campaign's)")
    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        base = Path(tmp) / "base.yaml"
        base.write_text("name: served-bench\nlamp: {watchdog_s: 10}\n")
        for campaign in args.campaigns:
            rig_file = Path(tmp) / f"{campaign.stem}-rig.yaml"
            server = subprocess.Popen(rig("sim", "serve", "--rig-file", str(rig_file), "--rig", str(base),
                                          "--campaign", str(campaign), "--speed", str(args.speed)),
                                      stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=os.environ)
            try:
                while not rig_file.exists():
                    if server.poll() is not None:
                        print(server.stderr.read(), file=sys.stderr)
                        return 1
                    time.sleep(0.01)
                served, served_wall = run(campaign, Path(tmp) / f"{campaign.stem}-served", "--rig", str(rig_file))
            finally:
                server.send_signal(signal.SIGTERM)
                _, log = server.communicate()
            local, local_wall = run(campaign, Path(tmp) / f"{campaign.stem}-local")
            for name, m, wall in (("served", served, served_wall), ("in-process", local, local_wall)):
                print(f"{campaign.name:28s} {name:10s}: {m['status']}, {m['counts']['measured']} points, "
                      f"rig time {m['rig_time_s'] / 60:6.1f} min, wall {wall:6.1f} s")
            print(f"{'':28s} served / in-process: rig time {served['rig_time_s'] / local['rig_time_s']:.2f}×, "
                  f"wall {served_wall / local_wall:.2f}×; lamp watchdog expiries in the served run: "
                  f"{log.count('communication watchdog')}")
            ok &= served["status"] == local["status"] == "complete"
            ok &= served["counts"]["measured"] == local["counts"]["measured"]
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
