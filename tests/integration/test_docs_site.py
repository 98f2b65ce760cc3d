"""The built book, looked at as a reader would: Debian's Chromium, driven by Playwright, opens
``docs/_build/html`` (what ``python -m sphinx -W -b html docs docs/_build/html`` writes; CI builds
it before the tests) and walks it from the index.

Every page reachable from the index is opened. On each, every link into the book must lead to a
file that exists and, when it names an anchor, to an element with that id; every ``<img>`` must
have loaded (an image outside the book is refused: a reader offline would see none). Then three
pages are looked at for what they must show: the index its figure, a notebook its figures, an API
page its entries. Where Chromium, Playwright or the built book is missing the tests skip with a
reason; with ``CI=true`` that is a failure.
"""

from __future__ import annotations

import os
from collections import deque
from pathlib import Path
from urllib.parse import unquote, urldefrag, urlparse

import pytest

from benchmarks.browser import CHROMIUM, CHROMIUM_ARGS

pytestmark = pytest.mark.slow

REPO = Path(__file__).resolve().parents[2]
SITE = REPO / "docs" / "_build" / "html"
BUILD = "python -m sphinx -W -b html docs docs/_build/html"

#: what a page reports about itself: its links, its images and the ids its anchors may name
SURVEY = """() => ({
  links: Array.from(document.querySelectorAll('a[href]'), a => a.href),
  images: Array.from(document.querySelectorAll('img'), i => ({
    src: i.currentSrc || i.src, loaded: i.complete && i.naturalWidth > 0, alt: i.alt})),
  ids: Array.from(document.querySelectorAll('[id], a[name]'), e => e.id || e.name),
  unexecuted: document.body.innerText.includes('was built on a machine without'),
})"""


def _missing(reason: str) -> None:
    if os.environ.get("CI", "").lower() in {"1", "true", "yes"}:
        pytest.fail(f"{reason}; CI must have it (.ci/run builds the book, installs Chromium)")
    pytest.skip(reason)


def _in_book(url: str) -> Path | None:
    """The file a file:// URL names, when it is inside the built book; None otherwise."""
    parsed = urlparse(url)
    if parsed.scheme != "file":
        return None
    path = Path(unquote(parsed.path))
    return path if path.is_relative_to(SITE) else None


@pytest.fixture(scope="module")
def page():
    if not (SITE / "index.html").is_file():
        _missing(f"the book is not built ({SITE}/index.html missing): {BUILD}")
    if not CHROMIUM.is_file():
        _missing(f"no Chromium at {CHROMIUM} (apt-get install chromium)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        _missing("Playwright for Python is not installed (pip install -r requirements-test.txt)")
    with sync_playwright() as p:
        browser = p.chromium.launch(
            executable_path=str(CHROMIUM), headless=True, args=CHROMIUM_ARGS
        )
        yield browser.new_page()
        browser.close()


@pytest.fixture(scope="module")
def walk(page) -> dict[Path, dict]:
    """{page file: its survey} of every page reachable from the index."""
    seen: dict[Path, dict] = {}
    todo = deque([SITE / "index.html"])
    while todo:
        path = todo.popleft()
        if path in seen:
            continue
        page.goto(path.as_uri(), wait_until="load")
        seen[path] = page.evaluate(SURVEY)
        for link in seen[path]["links"]:
            target = _in_book(urldefrag(link)[0])
            if target is not None and target.suffix == ".html" and target not in seen:
                if target.is_file():
                    todo.append(target)
    return seen


def test_no_link_in_the_book_is_broken(walk):
    broken = []
    for path, survey in walk.items():
        for link in survey["links"]:
            url, anchor = urldefrag(link)
            target = _in_book(url)
            if target is None:
                continue  # outside the book: the web, or a page's own search
            name = path.relative_to(SITE)
            if not target.is_file():
                broken.append(f"{name}: {target.relative_to(SITE)} does not exist")
            elif anchor and target in walk and unquote(anchor) not in walk[target]["ids"]:
                broken.append(f"{name}: {target.relative_to(SITE)} has no #{anchor}")
    assert len(walk) > 150  # the index, the notebooks, the guide, the studies, the API
    assert not broken, f"{len(broken)} broken links: {broken[:20]}"


def test_every_image_in_the_book_loads(walk):
    missing = [
        f"{path.relative_to(SITE)}: {image['src'][:100]} ({image['alt'][:40]!r})"
        for path, survey in walk.items()
        for image in survey["images"]
        if not image["loaded"] or not image["src"].startswith(("file:", "data:"))
    ]
    assert not missing, f"{len(missing)} images missing or outside the book: {missing[:20]}"


def test_the_index_shows_the_figure_and_links_every_part(walk):
    survey = walk[SITE / "index.html"]
    assert any(i["src"].endswith("octagon-2laps.png") and i["loaded"] for i in survey["images"])
    for part in ("notebooks.html", "instructor.html", "guide/index.html", "studies/index.html"):
        assert (SITE / part) in walk


def test_every_notebook_has_a_page_with_its_figures(walk):
    notebooks = sorted((REPO / "notebooks").glob("[0-9][0-9]-*.ipynb"))
    assert len(notebooks) >= 12
    for notebook in notebooks:
        path = SITE / "notebooks" / f"{notebook.stem}.html"
        assert path in walk, f"{notebook.name} has no page reachable from the index"
        if not walk[path]["unexecuted"]:  # built without its data: the page says so (never in CI)
            loaded = [i for i in walk[path]["images"] if i["loaded"]]
            assert loaded, f"{path.name} shows no figure"
    images = walk[SITE / "notebooks" / "06-full-slam.html"]["images"]
    figures = [i for i in images if i["loaded"] and i["src"].startswith("file:")]
    assert len(figures) >= 3  # Figure 2 of the runs, the covariance filling in, ...


def test_an_api_page_shows_its_entries(page, walk):
    path = SITE / "api" / "generated" / "ekfslam.pipeline.html"
    assert path in walk
    assert {"ekfslam.pipeline.replay", "ekfslam.pipeline.ReplayResult"} <= set(walk[path]["ids"])
    page.goto(path.as_uri() + "#ekfslam.pipeline.replay")
    signature = page.locator("dt[id='ekfslam.pipeline.replay']").inner_text()
    assert "replay(" in signature and "run" in signature
    assert (
        page.locator("dt[id='ekfslam.pipeline.replay'] + dd")
        .inner_text()
        .startswith("Run the EKF over a log")
    )
