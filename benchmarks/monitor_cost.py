"""Benchmark: what watching a run with `rig monitor` costs the run.

The monitor only reads the dataset folder, so it cannot change the run's data or rig time; what it could cost is
wall time (CPU and disk shared with the run). The quick campaign (campaigns/quick.yaml) is run in-process on the
simulated rig, alternately without a monitor and with one served on loopback and polled by `--viewers`
clients, each asking for the page's JSON every `--poll` seconds as the page does; the figure is the median wall
time of each over `--repeat` pairs, and their ratio. The rig time and the rows must be identical.

    python benchmarks/monitor_cost.py [--repeat 3] [--viewers 3] [--poll 0.5]
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import tempfile
import threading
import urllib.request
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rig.acquisition.run import run_campaign  # noqa: E402
from rig.bench.error_vs_time import machine  # noqa: E402
from rig.config.campaign import load_campaign  # noqa: E402
from rig.config.rigfile import simulated_rig  # noqa: E402
from rig.data.dataset_reader import load  # noqa: E402
from rig.monitor.server import make_server, page_url  # noqa: E402
from rig.session.connect import open_campaign_rig  # noqa: E402


def run(out: Path, viewers: int, poll_s: float) -> tuple[float, float, list[float]]:
    """(wall s, rig s, brdf values) of the quick campaign, watched by `viewers` pollers."""
    campaign, rig = load_campaign(ROOT / "campaigns" / "quick.yaml"), simulated_rig()
    server = make_server(out, "127.0.0.1", 0, None) if viewers else None
    stop = threading.Event()
    requests = [0]

    def viewer() -> None:
        assert server is not None
        url = page_url(server, None).rstrip("/") + "/api/state?since=0"
        while not stop.is_set():
            try:
                with urllib.request.urlopen(url, timeout=10) as reply:
                    json.load(reply)
                    requests[0] += 1
            except OSError:
                pass
            stop.wait(poll_s)

    threads = [threading.Thread(target=server.serve_forever, daemon=True)] if server else []
    threads += [threading.Thread(target=viewer, daemon=True) for _ in range(viewers)]
    for t in threads:
        t.start()
    try:
        outcome = run_campaign(campaign, rig, out, open_campaign_rig)
    finally:
        stop.set()
        if server is not None:
            server.shutdown()
            server.server_close()
    assert outcome.status == "complete"
    if viewers:
        print(f"    {requests[0]} monitor requests answered during the run")
    return outcome.wall_s, outcome.rig_time_s, list(load(out)["brdf_per_sr"])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--viewers", type=int, default=3)
    ap.add_argument("--poll", type=float, default=0.5, help="seconds between a viewer's requests (the page: 1)")
    args = ap.parse_args()
    print(f"machine: {machine()}")
    print(f"settings: quick campaign, {args.repeat} pairs, {args.viewers} viewers polling every {args.poll:g} s")
    walls: dict[int, list[float]] = {0: [], args.viewers: []}
    results = {}
    with tempfile.TemporaryDirectory() as tmp:
        for k in range(args.repeat):
            for viewers in (0, args.viewers):
                wall, rig_s, values = run(Path(tmp) / f"run{k}-{viewers}", viewers, args.poll)
                walls[viewers].append(wall)
                results.setdefault(viewers, (rig_s, values))
                print(f"  pair {k + 1}, {viewers} viewers: wall {wall:.2f} s, rig {rig_s:.1f} s")
    same = results[0] == results[args.viewers]
    base, watched = statistics.median(walls[0]), statistics.median(walls[args.viewers])
    print(f"median wall: unwatched {base:.2f} s, watched {watched:.2f} s, ratio {watched / base:.3f}")
    print(f"rig time and every BRDF value identical with and without the monitor: {same}")


if __name__ == "__main__":
    main()
