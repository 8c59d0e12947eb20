"""The site's tables sort by a click on a column's header (docs/javascripts/tablesort.js), checked in a headless
Chromium driven by Selenium: one committed scorecard page is built with the site's own mkdocs.yml (its theme,
Markdown extensions, extra CSS and JavaScript; no hooks, no plugins, so no notebook run), served on localhost and
clicked. The expected orders are computed here from the cells' text, independently of the script.

Needs Debian's Chromium and ChromeDriver (`apt-get install -y chromium chromium-driver`; .ci/run installs them):
without them the tests skip, which fails a CI run (tests/conftest.py)."""

from __future__ import annotations

import re
import shutil
import tempfile
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from functools import partial
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
#: the committed scorecard the tests render (its tables: numbers with intervals, `~` figures, `-` cells, names)
PAGE = Path("results/bench-v3-dev/scorecard.md")
CHROMIUM = Path("/usr/bin/chromium")
CHROMEDRIVER = Path("/usr/bin/chromedriver")
APT = "apt-get install -y chromium chromium-driver"
#: Chromium's flags on a closed network: without the networking ones it waits on services it cannot reach
CHROMIUM_FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
)


def build_site(out: Path, site_url: str, instant: bool = False) -> None:
    """Build `PAGE` (with its plots) and a home page linking to it into `out`/site with the site's mkdocs.yml,
    strict, for serving at `site_url`; `instant`: with Material's instant navigation (pages swapped in place)."""
    from mkdocs.commands.build import build
    from mkdocs.config import load_config

    docs = out / "docs"
    shutil.copytree(ROOT / "docs" / PAGE.parent, docs / PAGE.parent, ignore=shutil.ignore_patterns("*.json*"))
    (docs / "index.md").write_text(f"# Home\n\n[The scorecard]({PAGE.as_posix()})\n", encoding="utf-8")
    config = load_config(
        config_file=str(ROOT / "mkdocs.yml"),
        docs_dir=str(docs),
        site_dir=str(out / "site"),
        site_url=site_url,
        nav=[{"Home": "index.md"}, {"Scorecard": PAGE.as_posix()}],
        hooks=[],
        plugins=[],
    )
    assert config.strict, "mkdocs.yml builds strict: the pages must build without warnings"
    if instant:
        config.theme["features"].append("navigation.instant")
    for name in [*config.extra_css, *config.extra_javascript]:
        (docs / str(name)).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy(ROOT / "docs" / str(name), docs / str(name))
    build(config)


class QuietHandler(SimpleHTTPRequestHandler):
    def log_message(self, format, *args):  # the test's output is not an access log
        pass


@contextmanager
def served_site(instant: bool = False) -> Iterator[str]:
    """The built site on a local HTTP server (a thread): its root URL."""
    pytest.importorskip("mkdocs")
    with tempfile.TemporaryDirectory() as tmp:
        server = ThreadingHTTPServer(("127.0.0.1", 0), partial(QuietHandler, directory=str(Path(tmp) / "site")))
        url = f"http://127.0.0.1:{server.server_address[1]}/"
        build_site(Path(tmp), url, instant)
        thread = threading.Thread(target=server.serve_forever, daemon=True)
        thread.start()
        try:
            yield url
        finally:
            server.shutdown()
            server.server_close()


@pytest.fixture(scope="module")
def page_url() -> Iterator[str]:
    """The scorecard page's URL, for the module's tests."""
    with served_site() as url:
        yield url + PAGE.with_suffix("").as_posix() + "/"


@pytest.fixture(scope="module")
def browser():
    """A headless Chromium (Selenium, Debian's chromedriver) with a fresh profile."""
    missing = [str(p) for p in (CHROMIUM, CHROMEDRIVER) if not p.exists()]
    if missing:
        pytest.skip(f"{' and '.join(missing)} not found: install Chromium and ChromeDriver with `{APT}` (as root)")
    webdriver = pytest.importorskip("selenium.webdriver")
    from selenium.webdriver.chrome.service import Service

    with tempfile.TemporaryDirectory() as profile:
        options = webdriver.ChromeOptions()
        options.binary_location = str(CHROMIUM)
        for flag in (*CHROMIUM_FLAGS, f"--user-data-dir={profile}"):
            options.add_argument(flag)
        driver = webdriver.Chrome(service=Service(str(CHROMEDRIVER)), options=options)
        driver.set_page_load_timeout(30)
        try:
            yield driver
        finally:
            driver.quit()


@pytest.fixture
def page(browser, page_url):
    """The scorecard page, freshly loaded (no table sorted)."""
    browser.get(page_url)
    return browser


def tables(driver) -> list:
    return driver.find_elements("css selector", "article table")


def header_index(table, title: str) -> int:
    """The index of the column whose header starts with `title`."""
    heads = [th.text for th in table.find_elements("css selector", "thead th")]
    return next(i for i, head in enumerate(heads) if head.startswith(title))


def table_with(driver, first_heads: tuple[str, ...]):
    """The first table of the page whose header begins with `first_heads`."""
    for table in tables(driver):
        heads = tuple(th.text for th in table.find_elements("css selector", "thead th"))
        if heads[: len(first_heads)] == first_heads:
            return table
    raise AssertionError(f"no table with the headers {first_heads} on {PAGE}")


def rows(driver, table) -> list[list[str]]:
    """The table's body, row by row, as the page shows it now."""
    return driver.execute_script(
        "return Array.from(arguments[0].tBodies[0].rows, r => Array.from(r.cells, c => c.textContent.trim()));", table
    )


def click_header(table, index: int) -> None:
    table.find_elements("css selector", "thead th")[index].find_element("css selector", "button").click()


def aria_sort(table, index: int) -> str | None:
    return table.find_elements("css selector", "thead th")[index].get_attribute("aria-sort")


def number(text: str) -> float | None:
    """A scorecard cell's figure: `91% [88-94]` 91, `~4000` 4000, `2.5 s` 2.5; `-` and empty cells None."""
    if text in ("", "-"):
        return None
    m = re.match(r"~?(\d+(?:\.\d+)?(?:e[+-]\d+)?)", text)
    assert m, f"not a scorecard figure: {text!r}"
    return float(m.group(1))


def test_every_table_of_the_page_gets_a_sort_button_on_every_header(page):
    found = tables(page)
    assert len(found) >= 10
    for table in found:
        heads = table.find_elements("css selector", "thead th")
        assert heads and all(th.find_elements("css selector", "button.mobman-sort") for th in heads)
    assert page.find_element("css selector", "article table thead th button").get_attribute("type") == "button"


@pytest.mark.parametrize(
    ("first_heads", "column"),
    [
        (("controller", "knowledge"), "max error IQM"),  # `~600 [600-700]` beside `1.09 [1.05-1.13]`
        (("controller", "knowledge", "20 s"), "fastest tracked"),  # `2.5 s`, `5 s`, `10 s` and `-`
    ],
)
def test_a_numeric_column_sorts_by_value_and_a_second_click_reverses_it(page, first_heads, column):
    table = table_with(page, first_heads)
    index = header_index(table, column)
    before = rows(page, table)
    assert aria_sort(table, index) is None
    for direction, reverse in (("ascending", False), ("descending", True)):
        click_header(table, index)
        after = rows(page, table)
        assert sorted(map(tuple, after)) == sorted(map(tuple, before)), "rows lost or mixed"
        values = [number(row[index]) for row in after]
        present = [v for v in values if v is not None]
        assert values == present + [None] * (len(values) - len(present)), f"empty cells not last: {values}"
        assert present == sorted(present, reverse=reverse), f"{column} not {direction}: {present}"
        assert len(set(present)) > 2  # a column of one value would prove nothing
        assert aria_sort(table, index) == direction


def test_a_text_column_sorts_alphabetically_and_the_header_button_works_from_the_keyboard(page):
    from selenium.webdriver.common.keys import Keys

    table = table_with(page, ("controller", "knowledge"))
    numeric = header_index(table, "p90")
    click_header(table, numeric)  # sorted by another column first: the text sort must not depend on the page's order
    names = [row[0] for row in rows(page, table)]
    assert names != sorted(names, key=str.casefold)
    button = table.find_elements("css selector", "thead th")[0].find_element("css selector", "button")
    button.send_keys(Keys.ENTER)
    names = [row[0] for row in rows(page, table)]
    assert names == sorted(names, key=str.casefold)
    assert aria_sort(table, 0) == "ascending" and aria_sort(table, numeric) is None
    button.send_keys(Keys.SPACE)
    assert [row[0] for row in rows(page, table)] == sorted(names, key=str.casefold, reverse=True)
    assert aria_sort(table, 0) == "descending"


def test_tables_sort_after_material_instant_navigation(browser):
    """With `navigation.instant` (not on in mkdocs.yml today) Material swaps pages into the same document: the
    script, run once, must still reach the new page's tables (it follows Material's `document$`)."""
    from selenium.webdriver.support.ui import WebDriverWait

    with served_site(instant=True) as url:
        browser.get(url)
        browser.execute_script("window.mobmanSamePage = true;")
        browser.find_element("link text", "The scorecard").click()
        WebDriverWait(browser, 10).until(lambda d: len(tables(d)) > 1)
        assert browser.execute_script("return window.mobmanSamePage === true;"), "instant navigation did not happen"
        table = table_with(browser, ("controller", "knowledge"))
        click_header(table, 0)
        names = [row[0] for row in rows(browser, table)]
        assert names == sorted(names, key=str.casefold)
