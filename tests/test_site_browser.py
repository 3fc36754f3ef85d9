"""The results page in a real browser (headless Chromium driven by Selenium): every table has its
rows, a click on a column's header reorders them, every figure loads, and the console shows no
error. A screenshot of the index lands in a temporary folder (its path is printed).

Built from the shipped set and a small evaluation of one method, as a user's page is. Skipped,
with the reason, only where no Chromium and chromedriver are installed (.ci/run installs
Debian's `chromium` and `chromium-driver`)."""

from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import pytest

from ata.site import build_site
from _support import greedy_pair_suite

BROWSER = shutil.which("chromium") or shutil.which("chromium-browser") or \
    shutil.which("google-chrome")
DRIVER = shutil.which("chromedriver")
REQUIRED = os.environ.get("ATA_REQUIRE_BROWSER", "") not in ("", "0")
"""Set by .ci/run: there, a missing browser fails the test instead of skipping it."""
MISSING = ("no Chromium and chromedriver on this machine (Debian: apt-get install chromium "
           "chromium-driver)" if BROWSER is None or DRIVER is None else None)
if REQUIRED and MISSING:
    raise RuntimeError(f"ATA_REQUIRE_BROWSER is set but there is {MISSING}")
if REQUIRED:
    from selenium import webdriver      # CI installs the test extra: no skipping there
else:
    webdriver = pytest.importorskip("selenium.webdriver", reason="selenium is not installed "
                                    "(pip install -e '.[test]')")
pytestmark = pytest.mark.skipif(MISSING is not None, reason=str(MISSING))

SUITE = greedy_pair_suite(3, "mine")


@pytest.fixture(scope="module")
def page(tmp_path_factory):
    """The built page, opened in headless Chromium."""
    from selenium.webdriver.chrome.service import Service   # the optional browser test's

    root = tmp_path_factory.mktemp("site")
    (root / "suite.toml").write_text(SUITE)
    from ata.experiment.evaluate import evaluate_suites
    evaluate_suites([str(root / "suite.toml")], root / "mine", executor="serial")
    site = build_site(["published", str(root / "mine")], root / "site")
    options = webdriver.ChromeOptions()
    options.binary_location = BROWSER
    for flag in ("--headless=new", "--no-sandbox", "--disable-dev-shm-usage",
                 "--disable-gpu", "--window-size=1400,1800"):
        options.add_argument(flag)
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(DRIVER), options=options)
    try:
        yield driver, site
    finally:
        driver.quit()


def _errors(driver) -> list[str]:
    return [e["message"] for e in driver.get_log("browser") if e["level"] == "SEVERE"]


def test_every_table_has_its_rows_and_every_figure_loads(page):
    driver, site = page
    driver.get((site.out / "index.html").resolve().as_uri())
    tables = driver.find_elements("css selector", "table.sortable")
    groups = site.board.groups()
    assert len(tables) == 1 + len(groups)                 # the sets, then a board per cell
    for table, (setting, level) in zip(tables[1:], groups):
        rows = table.find_elements("css selector", "tbody tr")
        # every method's row, a method's seeds as one row across them
        shown = [e for e in site.board.table(setting, level) if not e.seed_of]
        assert len(rows) == len(shown) + len(site.board.seed_table(setting, level)) >= 2, \
            (setting, level)
    assert len(tables[0].find_elements("css selector", "tbody tr")) == 2
    images = driver.find_elements("css selector", "figure img")
    assert len(images) == len([f for f in site.files if f.endswith(".png")]) >= 3
    for img in images:
        assert driver.execute_script("return arguments[0].complete && "
                                     "arguments[0].naturalWidth", img) > 0, \
            img.get_attribute("src")
    shot = Path(tempfile.mkdtemp(prefix="ata-site-")) / "index.png"
    driver.save_screenshot(str(shot))
    print(f"screenshot: {shot}")
    assert shot.stat().st_size > 10_000
    assert _errors(driver) == []


def test_clicking_a_header_sorts_the_rows_and_a_second_click_turns_them_round(page):
    driver, site = page
    driver.get((site.out / "index.html").resolve().as_uri())
    table = driver.find_elements("css selector", "table.sortable")[1]

    def column(k: int) -> list[str]:
        return [r.find_elements("css selector", "td")[k].get_attribute("data-v")
                for r in table.find_elements("css selector", "tbody tr")]

    heads = table.find_elements("css selector", "thead th")
    names = [h.text for h in heads]
    k = names.index("method")
    before = column(k)
    heads[k].click()
    ascending = column(k)
    assert ascending == sorted(before, key=str.lower) and ascending != before
    assert heads[k].get_attribute("aria-sort") == "ascending"
    heads[k].click()
    assert column(k) == ascending[::-1]
    m = names.index("mean score")
    heads[m].click()
    means = [float(v) for v in column(m)]
    assert means == sorted(means)
    assert _errors(driver) == []


def test_a_method_page_opens_from_its_row_and_shows_its_provenance(page):
    driver, site = page
    driver.get((site.out / "index.html").resolve().as_uri())
    link = driver.find_element("link text", "ATA-HRL")
    link.click()
    text = driver.find_element("tag name", "body").text
    shot = Path(tempfile.mkdtemp(prefix="ata-site-")) / "method.png"
    driver.save_screenshot(str(shot))
    print(f"screenshot: {shot}")
    for word in ("code digest", "model revision", "trainer seed 12345", "ata run mission.toml",
                 "decisions isolated", "seed"):
        assert word in text, word
    assert _errors(driver) == []


def test_a_methods_row_across_seeds_opens_the_page_of_each_seed(page):
    driver, site = page
    driver.get((site.out / "index.html").resolve().as_uri())
    links = driver.find_elements("link text", "ATA-HRL (5 seeds)")
    assert len(links) == len(site.board.groups())         # one row in every board
    links[0].click()
    text = driver.find_element("tag name", "body").text
    for word in ("Across seeds", "IQM", "P(a seed beats greedy)", "ATA-HRL (one run)"):
        assert word in text, word
    seeds = driver.find_elements("css selector", "#table-each-seed tbody tr")
    assert len(seeds) == 5 * len(site.board.groups())
    driver.find_element("link text", "ATA-HRL seed 4").click()
    assert "code digest" in driver.find_element("tag name", "body").text
    assert _errors(driver) == []
