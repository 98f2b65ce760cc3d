"""The built book with the network cut, as in a classroom with a bad connection.

Debian's Chromium, driven by Playwright, opens every page of ``docs/_build/html`` (what
``python -m sphinx -W -b html docs docs/_build/html`` writes) with every request that is not a
local file refused, waits for MathJax to typeset, and counts on each page what a reader would
see wrong:

- ``external``: a request outside the book (a CDN's MathJax, require.js, font-awesome, ...);
- ``latex``: LaTeX left untypeset in the text (``\\(``, ``$$``, ``\\begin{``, ``\\frac`` ...);
- ``tables``: a Markdown table shown as pipe text (a ``|---|`` line);
- ``directives``: reST or MyST handed to the page as text (``.. autosummary::``,
  ``:nosignatures:``);
- ``reprs``: an object's repr (``<matplotlib.legend.Legend at 0x...>``), a bare ``False``;
- ``stubs``: the students' stub noise: the stubs' markers (``# YOUR CODE HERE``, ``raise
  NotImplementedError``, ``# BEGIN SOLUTION``) anywhere on a chapter and in any page's prose,
  and a chapter's "not done yet" or "Not answered yet" in its prose or outputs: the book shows
  the worked chapter.

Every count must be 0. ``python tests/integration/test_book_offline.py`` prints the six totals
and the worst pages. It also searches the book offline and checks that a concept finds a chapter
first. Without the built book, Chromium or Playwright the tests skip with a reason; with
``CI=true`` that is a failure (``.ci/run`` builds the book first).
"""

from __future__ import annotations

import os
import re
import sys
from collections import Counter
from pathlib import Path
from urllib.parse import quote

import pytest

REPO = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(REPO))

from benchmarks.browser import CHROMIUM, CHROMIUM_ARGS  # noqa: E402  (the checkout, above)

pytestmark = pytest.mark.slow

SITE = REPO / "docs" / "_build" / "html"
BUILD = "python -m sphinx -W -b html docs docs/_build/html"
COUNTS = ("external", "latex", "tables", "directives", "reprs", "stubs")

#: the page's text as a reader sees it, in three parts: the prose and outputs (code listings
#: and typeset math removed), the outputs alone, and everything including the code cells
TEXTS = """async () => {
  if (window.MathJax && MathJax.startup && MathJax.startup.promise) {
    await MathJax.startup.promise;
  }
  const body = document.querySelector('article') || document.body;
  const reading = body.cloneNode(true);
  for (const e of reading.querySelectorAll(
      'script, style, mjx-container, .cell_input, .headerlink, textarea')) e.remove();
  for (const e of reading.querySelectorAll('div[class*="highlight-"], pre, code')) {
    if (!e.closest('.cell_output')) e.remove();
  }
  const everything = body.cloneNode(true);
  for (const e of everything.querySelectorAll('script, style, mjx-container')) e.remove();
  const bare = Array.from(body.querySelectorAll('.cell_output .output'),
                          e => e.textContent.trim())
                    .filter(t => ['False', 'True', 'None'].includes(t)).length;
  return {reading: reading.textContent, everything: everything.textContent, bare: bare};
}"""

LATEX = re.compile(
    r"\\[()\[\]]|\$\$|\\(?:begin|end)\{|\\(?:frac|mathbf|mathrm|hat|Sigma|sigma|theta|omega"
    r"|partial|cdot|top|sqrt|left|right)\b|\$[^$\n]{0,80}?\\[A-Za-z]+"
)
#: a table's rule line; smart quotes make its "---" an em dash "—" in the page's text
TABLE = re.compile(r"\|\s*:?(?:-{3,}|[—–]+):?\s*\|")
DIRECTIVE = re.compile(
    r"^\s*\.\. [a-z][a-z:-]*::|:(?:nosignatures|toctree|recursive|no-members|members):"
    r"|```\{",
    re.M,
)
REPR = re.compile(r"<[^<>\n]{1,120} at 0x[0-9a-fA-F]+>|<Figure size \d|\b\w+\(children=\(")
#: the stubs' markers, wherever a page shows them, code included
MARKERS = re.compile(r"YOUR CODE HERE|NotImplementedError|(?:BEGIN|END) (?:SOLUTION|HIDDEN TESTS)")
#: what a check prints for an open exercise: noise in a chapter's prose and outputs (its code
#: may handle the open case); the guides quote these messages to the instructor
MESSAGES = re.compile(r"not done yet|not answered yet", re.I)
STUB = re.compile(f"{MARKERS.pattern}|{MESSAGES.pattern}", re.I)
LOCAL = ("file:", "data:", "blob:", "about:")


def _missing(reason: str) -> None:
    if os.environ.get("CI", "").lower() in {"1", "true", "yes"}:
        pytest.fail(f"{reason}; CI must have it (.ci/run builds the book, installs Chromium)")
    pytest.skip(reason)


def pages() -> list[Path]:
    return sorted(p for p in SITE.rglob("*.html") if "_static" not in p.parts)


def count_page(page, path: Path, refused: list[str]) -> Counter:
    """The six counts of one page (`refused` collects the requests the route refused)."""
    del refused[:]
    page.goto(path.as_uri(), wait_until="load")
    texts = page.evaluate(TEXTS)
    reading, everything = texts["reading"], texts["everything"]
    # a chapter: the markers count in its code too, the messages in its prose and outputs;
    # another page: the markers in its prose (its code blocks, the lab guide's, may show them);
    # the API reference documents the lab's machinery (make_lab.STUB's value) and is left out
    notebook = path.parent.name == "notebooks"
    api = path.relative_to(SITE).parts[0] == "api"
    stubs = len(MARKERS.findall(everything if notebook else reading))
    stubs += len(MESSAGES.findall(reading)) if notebook else 0
    return Counter(
        external=len(refused),
        latex=len(LATEX.findall(reading)),
        tables=len(TABLE.findall(reading)),
        directives=len(DIRECTIVE.findall(reading)),
        reprs=len(REPR.findall(reading)) + texts["bare"],
        stubs=0 if api else stubs,
    )


def _browser(p):
    return p.chromium.launch(executable_path=str(CHROMIUM), headless=True, args=CHROMIUM_ARGS)


def _offline_page(browser, refused: list[str]):
    page = browser.new_page()

    def route(r):
        if r.request.url.startswith(LOCAL):
            r.continue_()
        else:
            refused.append(r.request.url)
            r.abort()

    page.route("**/*", route)
    return page


def survey() -> dict[str, Counter]:
    """{page: its counts} of every page of the built book, opened offline."""
    from playwright.sync_api import sync_playwright  # lazy: a test dependency only

    found = {}
    with sync_playwright() as p:
        browser = _browser(p)
        refused: list[str] = []
        page = _offline_page(browser, refused)
        for path in pages():
            counts = count_page(page, path, refused)
            counts["refused"] = 0
            found[str(path.relative_to(SITE))] = counts
        browser.close()
    return found


#: the pages a closing note shows offline, and where on each to look (a script run's
#: ``--screenshots DIR``): a Markdown table, typeset equations, the API index
SHOTS = {
    "07-alignment": ("notebooks/07-alignment.html", "section#table-1-reproduced table"),
    "05-correction": ("notebooks/05-correction.html", "section#the-equations h2"),
    "api-index": ("api/index.html", "h1"),
}
TYPESET = """async () => {
  if (window.MathJax && MathJax.startup && MathJax.startup.promise) {
    await MathJax.startup.promise;
  }
}"""


def screenshots(folder: Path) -> list[str]:
    """`SHOTS` taken offline into `folder` (1280x900 px); returns the requests refused."""
    from playwright.sync_api import sync_playwright  # lazy: a test dependency only

    folder.mkdir(parents=True, exist_ok=True)
    refused: list[str] = []
    with sync_playwright() as p:
        browser = _browser(p)
        page = _offline_page(browser, refused)
        page.set_viewport_size({"width": 1280, "height": 900})
        for name, (relative, target) in SHOTS.items():
            page.goto((SITE / relative).as_uri())
            page.evaluate(TYPESET)
            page.locator(target).first.evaluate("e => e.scrollIntoView({block: 'center'})")
            page.screenshot(path=str(folder / f"{name}.png"))
        browser.close()
    return refused


def search_results(query: str) -> list[str]:
    """The pages the book's own search lists for `query`, best first, searched offline."""
    from playwright.sync_api import sync_playwright  # lazy: a test dependency only

    with sync_playwright() as p:
        browser = _browser(p)
        page = _offline_page(browser, [])
        page.goto((SITE / "search.html").as_uri() + f"?q={quote(query)}")
        page.wait_for_function(
            "() => (document.querySelector('#search-results p.search-summary') || {})"
            ".innerText?.includes('found')",
            timeout=60_000,
        )
        hrefs = page.eval_on_selector_all(
            "#search-results ul.search li a", "a => a.map(x => x.href)"
        )
        browser.close()
    return [h.split("/html/", 1)[-1] for h in hrefs]


@pytest.fixture(scope="module")
def book():
    if not (SITE / "index.html").is_file():
        _missing(f"the book is not built ({SITE}/index.html missing): {BUILD}")
    if not CHROMIUM.is_file():
        _missing(f"no Chromium at {CHROMIUM} (apt-get install chromium)")
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        _missing("Playwright for Python is not installed (pip install -r requirements-test.txt)")
    return SITE


@pytest.fixture(scope="module")
def counts(book) -> dict[str, Counter]:
    return survey()


@pytest.mark.parametrize("kind", COUNTS)
def test_no_page_shows_it_offline(counts, kind):
    assert len(counts) > 150  # the index, the notebooks, the guide, the studies, the API
    bad = {page: c[kind] for page, c in counts.items() if c[kind]}
    assert sum(bad.values()) == 0, f"{kind}: {sum(bad.values())} on {len(bad)} pages: {bad}"


def test_the_counts_see_what_they_count():
    """Each pattern finds the fault it names, and not the text around a fixed page."""
    assert len(LATEX.findall(r"the update \(K = P H^T\) and $$\frac{a}{b}$$")) >= 3
    assert TABLE.findall("| a | b |\n|---|---:|\n| 1 | 2 |")
    assert TABLE.findall("| a | b |\n|—|—:|\n| 1 | 2 |")
    assert DIRECTIVE.findall(".. autosummary::\n   :nosignatures:\n")
    assert REPR.findall("<matplotlib.legend.Legend at 0x7f3a2b1c>")
    assert STUB.findall("Exercise 3: not done yet. # YOUR CODE HERE")
    fine = "The filter's update, K = Σ Hᵀ S⁻¹; a table | a | b | of costs ($5)."
    assert not (LATEX.findall(fine) or TABLE.findall(fine) or REPR.findall(fine))


@pytest.mark.parametrize("query", ["Jacobian", "replay"])
def test_a_concept_finds_a_chapter_first(book, query):
    results = search_results(query)
    assert results, f"the search for {query!r} found nothing"
    first = results[0]
    assert first.startswith("notebooks/"), f"{query!r}: first {first}, then {results[1:5]}"


if __name__ == "__main__":
    if sys.argv[1:2] == ["--screenshots"]:
        refused = screenshots(Path(sys.argv[2]))
        print(f"{len(SHOTS)} pages in {sys.argv[2]}, {len(refused)} requests refused")
        sys.exit(0)
    found = survey()
    totals = sum(found.values(), Counter())
    print(f"{len(found)} pages, offline:")
    for kind in COUNTS:
        worst = sorted(((c[kind], page) for page, c in found.items() if c[kind]), reverse=True)
        print(f"  {kind:10} {totals[kind]:6}   {', '.join(f'{p} {n}' for n, p in worst[:4])}")
    for query in ("Jacobian", "replay"):
        results = search_results(query)
        print(f"search {query!r}: {results[:3]} ({len(results)} results)")
