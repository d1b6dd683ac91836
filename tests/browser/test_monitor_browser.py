"""`rig monitor` in headless Chromium while `rig run` measures: the count shown rises, the plots draw, a
burnt-out lamp shows as `paused` with the lamp suspender's reason, and the page asks nothing of any server
but the monitor.

The rig is the simulated one served like hardware (rig.simulators.served, as `rig sim serve` runs it, but
in this process so that the test can burn the lamp out and fit a new one: `inject("burnout")` and
`world.lamp.replace()`, what rig.simulators.faults does in the soak runs); `rig run --rig` drives it from
another process over the real protocols, and the monitor serves the dataset folder from this one. Waits
are bounded by rig_process.HANG_S as a hang guard, never asserted on.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
import yaml
from shared import Folder, warm

from browser_support import requested_urls
from repo_paths import TEST_CAMPAIGNS
from rig.config.rigfile import RigConfig
from rig.monitor.server import make_server, page_url
from rig.simulators.served import PAPER_RM1, ServedRig, write_rig_file
from rig_process import HANG_S, start_rig

#: Rig seconds per wall second of the served world; with the supply's 10 s watchdog the client has 2 s of
#: wall time between two lamp commands (as in tests/cli/test_sim_serve.py).
SPEED = 5.0
WATCHDOG_S = 10.0
#: tests/campaigns/served.yaml (16 points) with a warm-up of a few rig seconds (the simulated lamp is within
#: 0.1 % of its output 2 s apart from switch-on) and the lamp suspender checked every rig second.
CAMPAIGN_CHANGES = {"lamp": {"warmup_min_s": 4, "warmup_check_s": 2, "warmup_stable_rel": 0.05},
                    "suspenders": {"check_interval_s": 1}}
#: Points measured before the lamp burns out.
BURN_AFTER = 4
#: Pause between two looks at the page (wall seconds); the page polls every second.
LOOK_S = 0.1


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[ServedRig, Path]]:
    """The served simulated rig (ticking in a thread, so that its supply's watchdog acts) and its rig file."""
    rig = ServedRig(RigConfig.model_validate({"name": "bench", "lamp": {"watchdog_s": WATCHDOG_S}}), *PAPER_RM1,
                    speed=SPEED)
    rig_file = tmp_path / "served.yaml"
    write_rig_file(rig.start(), rig_file)
    stop = threading.Event()

    def tick() -> None:
        while not stop.wait(0.005):
            rig.tick()
    ticker = threading.Thread(target=tick, daemon=True)
    ticker.start()
    try:
        yield rig, rig_file
    finally:
        stop.set()
        ticker.join(HANG_S)
        rig.stop()


@pytest.fixture
def monitor(tmp_path: Path) -> Iterator[tuple[str, Path]]:
    """`rig monitor` of a folder that does not exist yet: its page's address and the folder."""
    folder = tmp_path / "run"
    server = make_server(folder, "127.0.0.1", 0, None)
    threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True).start()
    try:
        yield page_url(server, None), folder
    finally:
        server.shutdown()
        server.server_close()


def shown(browser, element: str) -> str:
    """An element's text as the page wrote it (before CSS's upper case)."""
    return browser.find_element("id", element).get_attribute("textContent")


def look_until(browser, proc, what: str, ready) -> None:
    """Look at the page until `ready()`; fail if it never comes (hang guard) or the run ends first."""
    for _ in range(int(HANG_S / LOOK_S)):
        if ready():
            return
        if proc is not None and proc.poll() is not None:
            pytest.fail(f"rig run ended (exit {proc.returncode}) before the page showed {what}: {proc.stderr.read()}")
        time.sleep(LOOK_S)
    pytest.fail(f"the page never showed {what}: phase {shown(browser, 'phase')!r}, {shown(browser, 'done')} points")


def inked_pixels(browser, canvas: str) -> int:
    """Pixels of a canvas that something was drawn on."""
    return browser.execute_script(
        "const c = document.getElementById(arguments[0]);"
        "const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;"
        "let n = 0; for (let i = 3; i < d.length; i += 4) if (d[i] > 0) n++; return n;", canvas)


def test_the_monitor_follows_a_run_through_a_pause(browser, served, monitor, tmp_path):
    rig, rig_file = served
    url, folder = monitor
    campaign = {**yaml.safe_load((TEST_CAMPAIGNS / "served.yaml").read_text()), **CAMPAIGN_CHANGES}
    campaign_file = tmp_path / "campaign.yaml"
    campaign_file.write_text(yaml.safe_dump(campaign))
    browser.get("about:blank")                                # an earlier test's page stops asking...
    requested_urls(browser)                                   # ...and what it left is drained
    browser.get(url)
    look_until(browser, None, "the wait for the folder", lambda: shown(browser, "phase") == "waiting")

    run = start_rig("run", str(campaign_file), "--rig", str(rig_file), "--out", str(folder), "--quiet")
    counts: list[int] = []

    def done() -> int:
        counts.append(int(shown(browser, "done")))
        return counts[-1]
    look_until(browser, run, f"{BURN_AFTER} points", lambda: done() >= BURN_AFTER)
    assert shown(browser, "to-measure") == "16" and shown(browser, "phase") == "measuring"
    rig.lamp.inject("burnout")
    look_until(browser, run, "the pause", lambda: shown(browser, "phase") == "paused")
    detail = shown(browser, "detail")
    assert detail.startswith("lamp:") and "burnt out" in detail
    paused_at = done()
    assert int(browser.find_element("id", "polar").get_attribute("data-drawn")) >= 1
    assert int(browser.find_element("id", "plane").get_attribute("data-drawn")) >= 1
    assert inked_pixels(browser, "polar") > 2000 and inked_pixels(browser, "illuminance") > 2000
    browser.get_screenshot_as_file(str(tmp_path / "monitor-paused.png"))
    time.sleep(1.5)                                           # the run stays paused while the lamp is out
    assert shown(browser, "phase") == "paused" and done() == paused_at

    rig.world.lamp.replace()                                  # the operator fits a new lamp
    look_until(browser, run, "the run going on", lambda: done() > paused_at)
    run.communicate(timeout=HANG_S)
    assert run.returncode == 0
    look_until(browser, None, "the finished run", lambda: shown(browser, "phase") == "finished")
    # the lamp's pause discards the points no lamp check vouched for: up to LampOutOfTolerance.CHECK_EVERY_S of rig
    # time (about four simulated points), however many the page had shown when the lamp burnt out
    assert counts[0] < BURN_AFTER <= max(counts) and paused_at < done() == 16
    events = browser.find_element("id", "events").text
    assert "suspended" in events and "resumed" in events

    urls = requested_urls(browser)
    assert urls and all(u.startswith(url) for u in urls), [u for u in urls if not u.startswith(url)]


def test_with_a_token_the_printed_address_gives_a_working_page(browser, tmp_path):
    """`rig monitor --host` (issue 30, item 7): the page at the printed address, token included, loads its style
    sheet and script (they were refused without the token: the page said "connecting…" forever) and follows the
    folder, asking nothing without the token."""
    token = "t0ken-for-the-browser"
    server = make_server(tmp_path / "later", "127.0.0.1", 0, token)
    threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True).start()
    try:
        url = page_url(server, token)
        browser.get("about:blank")
        requested_urls(browser)
        browser.get(url)
        look_until(browser, None, "the wait for the folder", lambda: shown(browser, "phase") == "waiting")
        rules = browser.execute_script("return Array.from(document.styleSheets, s => s.cssRules.length);")
        assert len(rules) == 1 and rules[0] > 0
        (tmp_path / "later").mkdir()
        os.mkfifo(tmp_path / "later" / "events.jsonl")          # what cannot be read is said on the page
        look_until(browser, None, "the warning", lambda: "events.jsonl: a FIFO" in shown(browser, "warnings"))
        urls = requested_urls(browser)
        assert urls and all(u.startswith(url.split("?")[0]) and f"token={token}" in u for u in urls), urls
    finally:
        server.shutdown()
        server.server_close()


def test_the_page_shows_the_run_as_soon_as_it_loads(browser, tmp_path):
    """Issue 35: a screenshot taken at load showed "CONNECTING…" and empty plots; the server now puts the state in
    the page. The series buttons say θi and φi (they said "θi 70.0°" for three series)."""
    f = Folder(tmp_path / "run")
    warm(f)
    f.row("01-001", 105.0, theta_o=30.0, phi_o=180.0)
    f.row("01-002", 106.0, theta_o=40.0, phi_o=90.0)
    server = make_server(f.path, "127.0.0.1", 0, None)
    threading.Thread(target=server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True).start()
    try:
        browser.get(page_url(server, None))                    # returns at the load event: no waiting after it
        assert shown(browser, "phase") == "measuring" and shown(browser, "done") == "2"
        assert int(browser.find_element("id", "polar").get_attribute("data-drawn")) == 2
        assert inked_pixels(browser, "illuminance") > 500
        labels = [b.text for b in browser.find_elements("css selector", "#series-picker button")]
        assert "θi 30° φi 0°" in labels, labels
    finally:
        server.shutdown()
        server.server_close()
