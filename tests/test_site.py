"""The built site, read as a reader would: in headless Chromium, page by page.

Reads the book built once for the session (the ``built_site`` fixture of conftest.py, which runs the
README's build command, ``make book``, beside the library's tests), serves ``_build/html`` on
127.0.0.1 and opens the front page and every page listed in ``_toc.yml``. A page fails on

- a console error or an uncaught page error (there is no list of harmless ones);
- a failed request, or a response with an HTTP status of 400 or more, for the page or anything it loads;
- a math block not typeset by the locally shipped MathJax, a math error, or a display equation
  wider than the text column;
- an image that does not load, or one with no alt text (an img with no non-empty alt, an svg with
  no accessible name, an animation whose container and frame image both have none);
- a cell output longer than ``MAX_OUTPUT_LINES`` rendered lines (a table counts its body rows), one
  (a table) wider than the text column, or one with a line that wraps in its box (a printed table
  whose columns break apart, on screen and in print);
- a build marker (``MARKERS``) anywhere in the page's text, solutions included;
- a code block that scrolls sideways or is cut by the text column (solutions opened first).

Every page is opened in both editions: English (``_build/html``) and Vietnamese (``_build/html/vi``).
Besides: every generated page is reachable from the table of contents, a solution dropdown opens on
click, each page's link to the other edition opens the same page there, and every chapter downloads as
an executed notebook. A screenshot of every page lands in ``_build/screenshots`` to be looked at:
its first screen (1200 x 900), or the whole page with ``CLOSEDLOOP_FULL_SCREENSHOTS=1``. A full page
costs 1-2 s to capture, about as long as the page's checks, and the checks do not read it (they
measure the rendered page itself), so the default run does not pay for it. If Chromium is not
installed, the test is skipped and says so. With ``CLOSEDLOOP_SITE_BUILT=1`` the test reads the ``_build/html`` already built instead of
running ``make book``.
"""

import functools
import http.server
import os
import threading
from pathlib import Path

import pytest
from print_pdf import CHROMIUM_FLAGS, chromium    # the PDF's browser: Chromium's headless shell, else chromium

from ._toc import toc_pages

ROOT = Path(__file__).resolve().parents[1]
HTML = ROOT / "_build" / "html"
#: The longest cell output a page may show, in rendered lines (a wrapped line counts each time).
MAX_OUTPUT_LINES = 20
#: Text the build uses to cut solutions out; a reader must never see it.
MARKERS = ("BEGIN SOLUTION", "END SOLUTION", "STUDENT:")
#: Pages Sphinx writes that need no link from the table of contents.
UNLISTED = {"genindex.html", "search.html", "404.html"}
#: The editions, as folders of _build/html: English at the top, each translation in its own folder.
EDITIONS = ("", "vi/")
#: Whole-page screenshots (slow), instead of each page's first screen.
FULL_SCREENSHOTS = os.environ.get("CLOSEDLOOP_FULL_SCREENSHOTS") == "1"


@pytest.fixture(scope="module")
def site(built_site):
    browser_path = chromium()
    if not Path(browser_path).exists():
        pytest.skip(f"Chromium is not installed ({browser_path} not found), so the built site was NOT "
                    "checked in a browser: install Debian's chromium-headless-shell package (make test tries to)")

    class Quiet(http.server.SimpleHTTPRequestHandler):
        def log_message(self, *args):
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=str(HTML)))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    yield f"http://127.0.0.1:{server.server_address[1]}"
    server.shutdown()


@pytest.fixture(scope="module")
def browser(site):
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=chromium(), args=CHROMIUM_FLAGS)
        yield browser
        browser.close()


def open_page(browser, site, page_name):
    """The page in a 1200 x 900 window, with its math typeset, and the list its problems go to."""
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    problems = []
    page.on("console", lambda m: m.type == "error"
            and problems.append(f"console: {m.text} at {m.location.get('url')}"))
    page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
    # net::ERR_ABORTED is a load the browser dropped itself (the front page's redirect leaving); a missing
    # file is an HTTP status, caught below
    page.on("requestfailed", lambda r: "ERR_ABORTED" in (r.failure or "")
            or problems.append(f"request failed: {r.url} ({r.failure})"))
    page.on("response", lambda r: r.status >= 400 and problems.append(f"HTTP {r.status}: {r.url}"))
    # "load" (every script, stylesheet and image), then the typesetting and the fonts it asks for: every
    # request a page makes is made by then (measured: no request in the 1.5 s after, on any chapter).
    # "networkidle" waits 0.5 s more on every page for the same requests.
    page.goto(f"{site}/{page_name}.html", wait_until="load")
    if page_name.rsplit("/", 1)[-1] == "index":              # the front page sends the reader on at once
        page.wait_for_url(f"**/{toc_pages()[0]}.html", wait_until="load")
    if page.locator("div.math, span.math").count():          # MathJax is only loaded where there is math
        page.wait_for_function("() => window.MathJax && MathJax.startup && MathJax.startup.promise")
        page.evaluate("() => MathJax.startup.promise")
    page.evaluate("() => document.fonts.ready.then(() => true)")
    return page, problems


#: Every check that reads the rendered page, in one pass.
MEASURE = r"""() => {
    const article = document.querySelector('article') || document.body;
    const column = article.getBoundingClientRect();
    const blocks = [...document.querySelectorAll('div.math, span.math')];
    const renderedLines = (pre) => {
        const style = getComputedStyle(pre);
        const line = parseFloat(style.lineHeight) || 1.2 * parseFloat(style.fontSize);
        const height = pre.scrollHeight - parseFloat(style.paddingTop) - parseFloat(style.paddingBottom);
        return Math.max(pre.textContent.replace(/\n$/, '').split('\n').length, Math.round(height / line));
    };
    const longestLine = (pre) =>
        pre.textContent.split('\n').reduce((a, b) => a.length >= b.length ? a : b).slice(0, 100);
    const named = (e) => (e.getAttribute('alt') || e.getAttribute('aria-label') || '').trim() !== ''
        || !!(e.querySelector && e.querySelector('title') && e.querySelector('title').textContent.trim());
    return {
        math: {blocks: blocks.length, typeset: blocks.filter(b => b.querySelector('mjx-container')).length,
               errors: document.querySelectorAll('mjx-merror').length},
        wideMath: [...document.querySelectorAll('mjx-container[display="true"]')]
            .map(m => m.getBoundingClientRect())
            .filter(r => r.left < column.left - 1 || r.right > column.right + 1).length,
        images: [...article.querySelectorAll('img')].map(i => ({
            src: (i.getAttribute('src') || '').slice(0, 80), ok: i.complete && i.naturalWidth > 0,
            alt: (i.getAttribute('alt') || '').trim() !== ''})),
        unnamedSvg: [...article.querySelectorAll('svg')]
            .filter(s => !s.closest('[aria-hidden="true"], button, a') && !named(s))   // icons of controls aside
            .length,
        unnamedAnimations: [...article.querySelectorAll('div.animation')]
            .filter(a => !named(a) && ![...a.querySelectorAll('img')].every(named)).length,
        longOutputs: [...article.querySelectorAll('div.cell_output')].map(output => {
            const lines = [...output.querySelectorAll('pre')].map(renderedLines).reduce((a, b) => a + b, 0)
                + output.querySelectorAll('tbody tr').length;
            return {lines, start: output.textContent.trim().slice(0, 70)};
        }).filter(o => o.lines > %d),
        wrappedOutputs: [...article.querySelectorAll('div.cell_output pre')].filter(pre =>
            pre.offsetParent !== null && renderedLines(pre) > pre.textContent.replace(/\n$/, '').split('\n').length
        ).map(longestLine),
        markers: %s.filter(m => article.textContent.includes(m)),
        wideCode: [...article.querySelectorAll('pre')].filter(pre => {
            const r = pre.getBoundingClientRect();
            return pre.offsetParent !== null && (pre.scrollWidth > pre.clientWidth + 1 || r.right > column.right + 1);
        }).map(longestLine),
        wideTables: [...article.querySelectorAll('div.cell_output table, div.cell_output div.output')].filter(e => {
            const r = e.getBoundingClientRect();
            return e.offsetParent !== null && (e.scrollWidth > e.clientWidth + 1 || r.right > column.right + 1);
        }).map(e => e.textContent.trim().slice(0, 70)),
    };
}""" % (MAX_OUTPUT_LINES, list(MARKERS))

#: Opens every dropdown (sphinx-togglebutton, <details>) so that hidden code is measured too.
OPEN_EVERYTHING = """() => {
    document.querySelectorAll('.toggle-hidden').forEach(e => e.classList.remove('toggle-hidden'));
    document.querySelectorAll('details').forEach(d => d.open = true);
}"""


@pytest.mark.parametrize("page_name", [edition + page for edition in EDITIONS for page in ["index", *toc_pages()]])
def test_page_is_clean(browser, site, page_name):
    page, problems = open_page(browser, site, page_name)
    shots = ROOT / "_build" / "screenshots"
    shots.mkdir(exist_ok=True)
    page.screenshot(path=str(shots / (page_name.replace("/", "_") + ".png")), full_page=FULL_SCREENSHOTS)
    page.evaluate(OPEN_EVERYTHING)
    found = page.evaluate(MEASURE)
    page.close()
    math = found["math"]
    faults = problems + [f"{what}: {items}" for what, items in [
        ("math not typeset or in error", [] if math["typeset"] == math["blocks"] and not math["errors"] else [math]),
        ("display equations wider than the text column (1200 px)", found["wideMath"] or []),
        ("images that do not load", [i["src"] for i in found["images"] if not i["ok"]]),
        ("images with no alt text", [i["src"] for i in found["images"] if not i["alt"]]),
        ("svgs or animations with no alt text", found["unnamedSvg"] + found["unnamedAnimations"] or []),
        (f"outputs longer than {MAX_OUTPUT_LINES} lines", found["longOutputs"]),
        ("outputs whose lines wrap in their box (their longest lines)", found["wrappedOutputs"]),
        ("build markers in the page", found["markers"]),
        ("code blocks wider than the text column (their longest lines)", found["wideCode"]),
        ("outputs wider than the text column", found["wideTables"]),
    ] if items]
    assert faults == []
    if page_name.removeprefix("vi/").startswith("chapters/"):
        assert math["blocks"] > 0 and found["images"], "a chapter without math or figures"


@pytest.mark.parametrize("edition", EDITIONS)
def test_every_page_is_reachable_from_the_table_of_contents(site, edition):
    listed = {f"{name}.html" for name in toc_pages()} | {"index.html"}
    folder = HTML / edition
    others = {other.strip("/") for other in EDITIONS if other}
    built = {str(path.relative_to(folder)) for path in folder.rglob("*.html")
             if not path.relative_to(folder).parts[0].startswith("_") and path.relative_to(folder).parts[0] not in others}
    assert listed <= built, f"pages of the table of contents missing from the {edition or 'English'} edition"
    assert built - listed - UNLISTED == set(), "pages no reader can reach from the table of contents"


@pytest.mark.parametrize("page_name", ["chapters/06-four-cases", "exercises/03-baumgarte", "book/glossary"])
def test_the_edition_links_open_the_same_page(browser, site, page_name):
    """English to Vietnamese and back, by clicking the link at the top of the page."""
    page, problems = open_page(browser, site, page_name)
    english_title = page.locator("article h1").first.inner_text()
    page.locator("p.edition-links a[hreflang=vi]").click()
    page.wait_for_url(f"{site}/vi/{page_name}.html", wait_until="load")
    assert page.url == f"{site}/vi/{page_name}.html"
    assert page.evaluate("document.documentElement.lang") == "vi"
    assert page.locator("article h1").first.inner_text() != english_title     # the title is translated
    page.locator("p.edition-links a[hreflang=en]").click()
    page.wait_for_url(f"{site}/{page_name}.html", wait_until="load")
    assert page.url == f"{site}/{page_name}.html"
    assert page.locator("article h1").first.inner_text() == english_title
    page.close()
    assert problems == []


def test_mathjax_is_served_locally(site):
    page_html = (HTML / "chapters" / "01-closed-loop-systems.html").read_text()
    assert "_static/mathjax/tex-chtml.js" in page_html
    assert "cdn.jsdelivr" not in page_html and (HTML / "_static" / "mathjax" / "tex-chtml.js").exists()


@pytest.mark.parametrize("edition", EDITIONS)
def test_a_solution_dropdown_opens_on_click(browser, site, edition):
    page, problems = open_page(browser, site, edition + "chapters/01-closed-loop-systems")
    solution = page.locator("div.solution.dropdown").first
    body = solution.locator("section#solution-content").first
    assert "toggle-hidden" in solution.get_attribute("class")
    assert not body.is_visible()
    solution.locator("button.toggle-button").first.click()
    page.wait_for_timeout(300)
    assert "toggle-hidden" not in solution.get_attribute("class")
    assert body.is_visible()
    page.close()
    assert problems == []


def test_each_chapter_downloads_as_an_executed_notebook(site):
    """A chapter downloads as its executed notebook, an exercise page as its student version.

    tests/test_downloads.py reads every download's markdown and runs each one as a reader would.
    """
    import json

    for page_name in toc_pages():
        if not page_name.startswith(("chapters/", "exercises/")):
            continue
        html = (HTML / f"{page_name}.html").read_text()
        assert f"_sources/{page_name}.ipynb" in html, f"{page_name}: no .ipynb in the download menu"
        notebook = json.loads((HTML / "_sources" / f"{page_name}.ipynb").read_text())
        code = [c for c in notebook["cells"] if c["cell_type"] == "code"]
        outputs = [o for c in code for o in c["outputs"]]
        if page_name.startswith("exercises/"):      # not run: its first check would stop at its ...
            assert not outputs and "= ..." in "".join("".join(c["source"]) for c in code), \
                f"{page_name}: the download is not the student version"
            continue
        assert outputs, f"{page_name}: the downloadable notebook has no outputs"
        assert not [o for o in outputs if o["output_type"] == "error"]
