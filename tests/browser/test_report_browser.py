"""`rig report`'s page in a real browser (headless Chromium, tests/browser/conftest.py): opened from file://, it
renders its sections and every figure, asks the network for nothing but itself, and prints to a PDF of several
pages."""

import base64
import re

import pytest

from browser_support import requested_urls

SECTIONS = ("sample", "rig", "conditions", "counts", "budget", "figures", "fit", "road")


@pytest.fixture(scope="module")
def report_url(e2e_report):
    """The shared report (tests/conftest.py: the e2e run with a fit and road quantities)."""
    return (e2e_report["dir"] / "report.html").as_uri()


def test_the_report_renders_from_its_file_alone(browser, report_url):
    browser.get("about:blank")          # an earlier test's page (a polling monitor, say) stops asking...
    requested_urls(browser)             # ...and what it asked for is drained
    browser.get(report_url)
    assert browser.title.startswith("BRDF report")
    for ident in SECTIONS:
        element = browser.find_element("id", ident)
        assert element.is_displayed() and element.size["height"] > 50, ident
    widths = browser.execute_script(
        "return Array.from(document.images).map(i => i.complete ? i.naturalWidth : 0);")
    assert len(widths) >= 4 and min(widths) > 0, widths
    urls = requested_urls(browser)
    assert report_url in urls
    assert all(u == report_url or u.startswith("data:") for u in urls), urls


def test_the_report_prints_to_a_pdf_of_several_pages(browser, report_url):
    from selenium.webdriver.common.print_page_options import PrintOptions

    browser.get(report_url)
    # On a loaded machine headless Chromium can print a blank page (860 bytes, one page) when asked at the load
    # event, before the embedded figures are decoded and laid out: print once they are, after two frames.
    browser.set_script_timeout(60)
    browser.execute_async_script("""
        const done = arguments[arguments.length - 1];
        Promise.all(Array.from(document.images).map(i => i.decode().catch(() => null)))
            .then(() => requestAnimationFrame(() => requestAnimationFrame(() => done(true))));""")
    options = PrintOptions()
    options.page_width, options.page_height = 21.0, 29.7        # A4, cm
    pdf = base64.b64decode(browser.print_page(options))
    assert pdf.startswith(b"%PDF")
    pages = len(re.findall(rb"/Type\s*/Page(?!s)", pdf))
    assert pages >= 6, pages                                    # each section starts a page
