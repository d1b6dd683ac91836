"""A screenshot of `rig monitor` mid-run: the quick campaign on the paced simulated rig, served by the
monitor, photographed by headless Chromium (Debian's `chromium` and `chromium-driver`, and selenium).

The campaign is campaigns/quick.yaml with a short warm-up (that of tests/campaigns/served.yaml), so
that the ~3 min of rig time last ~20 s of wall time at RIG_SIM_PACE = 0.1; the picture is taken once
half of its points are measured.

    python benchmarks/monitor_screenshot.py OUT.png
    python benchmarks/monitor_screenshot.py --warm-up OUT.png     # during the warm-up, after a few checks
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from browser_support import CHROMEDRIVER_PATHS, CHROMIUM_ARGS, CHROMIUM_PATHS  # noqa: E402
from rig.monitor.server import make_server, page_url  # noqa: E402

#: Wall seconds per rig second of the run.
PACE = 0.1
#: The short warm-up of the served-rig test campaign: the simulated lamp is within 5 % after ~25 s.
WARMUP = {"warmup_min_s": 20, "warmup_check_s": 5, "warmup_stable_rel": 0.05}
#: A warm-up that checks E⊥ several times before it is steady (below the simulated meter's noise, 0.2 %).
LONG_WARMUP = {"warmup_min_s": 30, "warmup_check_s": 10, "warmup_stable_rel": 0.0005, "warmup_max_s": 300}
#: Fraction of the campaign's points measured when the picture is taken.
AT_FRACTION = 0.5
#: The browser window: tall enough for the whole page (tables included) in one picture.
WINDOW_PX = (1280, 1560)
#: Hang guard (wall seconds), not a measurement.
HANG_S = 180.0


def paced_campaign(folder: Path, warmup: dict = WARMUP) -> Path:
    campaign = yaml.safe_load((ROOT / "campaigns" / "quick.yaml").read_text())
    campaign["lamp"] = {**campaign.get("lamp", {}), **warmup}
    path = folder / "quick-paced.yaml"
    path.write_text(yaml.safe_dump(campaign, sort_keys=False))
    return path


def shown_points(driver) -> tuple[int, int]:
    """(measured, to measure) as the page shows them (0 of 0 before it knows)."""
    done = driver.find_element("id", "done").text
    total = driver.find_element("id", "to-measure").text
    return int(done or 0), int(total) if total.isdigit() else 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("out", metavar="OUT.png")
    parser.add_argument("--warm-up", action="store_true", help="take it during the warm-up, after two checks")
    args = parser.parse_args()
    out = Path(args.out)
    from selenium import webdriver

    chromium = next(p for p in CHROMIUM_PATHS if Path(p).exists())
    chromedriver = next(p for p in CHROMEDRIVER_PATHS if Path(p).exists())
    with tempfile.TemporaryDirectory(prefix="rig-monitor-shot-") as tmp:
        folder = Path(tmp) / "run"
        campaign = paced_campaign(Path(tmp), LONG_WARMUP if args.warm_up else WARMUP)
        run = subprocess.Popen([sys.executable, "-m", "rig.cli.main", "run", str(campaign),
                                "--out", str(folder), "--quiet"], env={**os.environ, "RIG_SIM_PACE": str(PACE)},
                               stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        server = make_server(folder, "127.0.0.1", 0, None)
        threading.Thread(target=server.serve_forever, daemon=True).start()
        options = webdriver.ChromeOptions()
        options.binary_location = chromium
        for arg in (*CHROMIUM_ARGS, f"--user-data-dir={tmp}/profile"):
            options.add_argument(arg)
        driver = webdriver.Chrome(options=options, service=webdriver.ChromeService(executable_path=chromedriver))
        try:
            driver.set_window_size(*WINDOW_PX)
            driver.get(page_url(server, None))
            deadline = time.monotonic() + HANG_S
            while True:
                done, total = shown_points(driver)
                if args.warm_up and driver.find_element("id", "detail").text.count("changed"):
                    break
                if total and done >= AT_FRACTION * total:
                    break
                if run.poll() is not None or time.monotonic() > deadline:
                    why = run.stderr.read() if run.stderr else ""
                    print(f"the run ended or hung before {AT_FRACTION:.0%} of its points: {why}", file=sys.stderr)
                    return 1
                time.sleep(0.2)
            time.sleep(1.2)                  # one more poll of the page, so the plots show the same points
            driver.get_screenshot_as_file(str(out))
            print(f"{out}: the monitor at {done} of {total} points")
        finally:
            driver.quit()
            run.terminate()
            run.wait()
            server.shutdown()
            server.server_close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
