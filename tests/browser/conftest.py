"""A real browser for the web pages rig writes (`rig report`) and serves (`rig monitor`): Debian's headless
Chromium driven through its ChromeDriver by Selenium. CI installs the packages (.ci/run); where they are absent
the tests are skipped with the reason, never passed."""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest

from browser_support import CHROMEDRIVER_PATHS, CHROMIUM_ARGS, CHROMIUM_PATHS, requested_urls


def _first(paths: tuple[str, ...]) -> str | None:
    return next((p for p in paths if Path(p).exists()), None)


@pytest.fixture(scope="session")
def browser() -> Iterator[object]:
    """A headless Chromium (selenium.webdriver.Chrome) with performance logging on, so that a test can list
    every request the page made (`requested_urls`)."""
    webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is not installed (pip install -e '.[test]')")
    chromium, driver_path = _first(CHROMIUM_PATHS), _first(CHROMEDRIVER_PATHS)
    if chromium is None or driver_path is None:
        pytest.skip("Debian's chromium and chromium-driver are not installed "
                    "(apt-get install chromium chromium-driver)")
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for arg in CHROMIUM_ARGS:
        options.add_argument(arg)
    profile = tempfile.mkdtemp(prefix="rig-chromium-")
    options.add_argument(f"--user-data-dir={profile}")
    options.set_capability("goog:loggingPrefs", {"performance": "ALL"})
    driver = webdriver.Chrome(options=options, service=webdriver.ChromeService(executable_path=driver_path))
    driver.set_page_load_timeout(60)
    driver.get("about:blank")
    requested_urls(driver)                       # drain the new-tab page's own requests
    try:
        yield driver
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)
