"""What the browser tests share besides the `browser` fixture (tests/browser/conftest.py): where Debian puts
Chromium and its ChromeDriver, the flags it needs on a closed network, and the list of requests a page made."""

from __future__ import annotations

import json

CHROMIUM_PATHS = ("/usr/bin/chromium", "/usr/bin/chromium-browser")
CHROMEDRIVER_PATHS = ("/usr/bin/chromedriver",)
#: The machine's network is closed: without these Chromium spends its start-up on refused connections
#: (updates, sync, field trials), and without --no-sandbox it does not start as root.
CHROMIUM_ARGS = ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                 "--disable-background-networking", "--disable-component-update", "--disable-sync",
                 "--disable-dev-shm-usage", "--window-size=1280,1000")


def requested_urls(driver: object) -> list[str]:
    """Every URL the page asked the network for since the last call (Chrome's performance log, drained)."""
    urls = []
    for entry in driver.get_log("performance"):  # type: ignore[attr-defined]
        message = json.loads(entry["message"])["message"]
        if message.get("method") == "Network.requestWillBeSent":
            urls.append(message["params"]["request"]["url"])
    return urls
