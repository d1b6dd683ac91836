"""A screenshot of `rig report`'s page: the report of DATASET written to a temporary file and photographed by
headless Chromium (`--screenshot`, the flags of the browser tests, tests/browser_support.py) at 1280 px wide.

    python benchmarks/report_screenshot.py DATASET OUT.png [--fit FIT.json] [--road road.json] [--height PX]
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from browser_support import CHROMIUM_ARGS, CHROMIUM_PATHS  # noqa: E402
from rig.cli.report import cmd_report  # noqa: E402

WIDTH_PX = 1280


def screenshot(html: Path, out: Path, height_px: int) -> None:
    """Chromium's own --screenshot of the page at WIDTH_PX × height_px (the last --window-size wins)."""
    chromium = next((p for p in CHROMIUM_PATHS if Path(p).exists()), None)
    if chromium is None:
        raise SystemExit("Chromium is not installed (apt-get install chromium)")
    with tempfile.TemporaryDirectory(prefix="rig-chromium-") as profile:
        subprocess.run([chromium, *CHROMIUM_ARGS, f"--user-data-dir={profile}", f"--window-size={WIDTH_PX},{height_px}",
                        "--hide-scrollbars", f"--screenshot={out.resolve()}", html.resolve().as_uri()],
                       check=True, capture_output=True, timeout=120)


def run() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("dataset")
    parser.add_argument("out", type=Path)
    parser.add_argument("--fit")
    parser.add_argument("--road")
    parser.add_argument("--height", type=int, default=2400, help="window height in pixels (default 2400)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="rig-report-") as tmp:
        html = Path(tmp) / "report.html"
        if cmd_report(argparse.Namespace(dataset=args.dataset, out=html, fit=args.fit, road=args.road)) != 0:
            return 2
        screenshot(html, args.out, args.height)
    print(f"screenshot of the report of {args.dataset} → {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(run())
