"""Print the book's single-page build to one PDF with Debian's headless Chromium, driven by Playwright.

    python book/print/print_pdf.py _build/singlehtml _build/pdf/closedloop.pdf

The input is Jupyter Book's single-page build (``jupyter-book build . --builder singlehtml``),
the same pages as the site with the site's numbering. The page is opened in headless Chromium,
served from 127.0.0.1 (nothing is fetched from the network: MathJax and BokehJS are in
``_static``), and once MathJax has typeset every formula and BokehJS has drawn every
interactive figure, ``prepare.js`` makes it a book: every exercise solution removed, and the pages
for instructors only (the rubrics), hidden code left out, each animation a still with a note, a title
page (the title, the authors, the version and its date, the downloads) and a table of contents in front,
each page of the site starting a printed page; ``print.css`` drops the site's navigation and
sets the type. Chromium prints it on A4 with the title in the header, page numbers in the
footer, and bookmarks from the headings.

The table of contents gives each entry's page. Chromium cannot say where its page breaks fall,
so the book is printed twice: ``pdfinfo -dests`` (poppler-utils) reads from the first print
the page of each entry's link target, and the second print carries those numbers (the first
print reserves their width, so the second breaks the pages the same way; this is checked, and
printed again if not).

The texts this script adds (the notes) are chosen by the page's language (``<html lang>``), so
the Vietnamese edition's single-page build prints with its own; ``TEXTS`` holds them.
"""

from __future__ import annotations

import argparse
import contextlib
import functools
import http.server
import re
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]


def chromium():
    """The browser to print with: Debian's headless shell of Chromium (package chromium-headless-shell,
    Chromium's old headless mode, which Playwright also uses for headless runs), else Debian's whole browser
    (package chromium), else the path the first would have. The same engine and the same PDF, but the whole
    browser ran a second busy renderer (``--top-chrome-webui``) beside each page's: twice the CPU time for
    the site test's pages. The site test (tests/test_site.py, tests/conftest.py) uses this one too. Looked up
    at each call: ``make test`` may install it while the tests run."""
    return shutil.which("chromium-headless-shell") or shutil.which("chromium") or "/usr/bin/chromium-headless-shell"


CHROMIUM_FLAGS = ["--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync"]
#: A4 with 15 mm side margins and room for the header and the footer.
PAPER = {"format": "A4", "margin": {"top": "18mm", "bottom": "18mm", "left": "15mm", "right": "15mm"}}
#: The text column's width in CSS pixels (180 mm at 96 px per inch): the window is opened this wide,
#: so that the interactive figures are laid out at the width they are printed at.
COLUMN_PX = 680
#: Files the single page links that Sphinx does not write for it (its search index); not an error.
NOT_WRITTEN = ("/searchindex.js",)
#: Notes added to the printed page, by language; ``{chapter}`` is the chapter's number.
TEXTS = {
    "en": {
        "animation": "Animation, shown here by its first frame: the web edition of chapter {chapter} plays it.",
        "interactive": "Interactive figure: in the web edition of chapter {chapter}, hover over it and "
                       "click it to explore.",
    },
    "vi": {
        "animation": "Hình động, ở đây chỉ in khung hình đầu tiên: bản web của chương {chapter} "
                     "phát toàn bộ.",
        "interactive": "Hình tương tác: trong bản web của chương {chapter}, di chuột và nhấp vào hình "
                       "để khám phá.",
    },
}
#: The title page's lines under the title and the authors, by language; the values come from the page's
#: ``<meta>`` tags (``closedloop:version`` and the like, book/_ext/companion.py).
TITLE_PAGE = {
    "en": {
        "version": "Version {version}, {date}",
        "downloads": "Every chapter runs on your computer: the web edition's landing page offers the library, "
                     "{wheel}, and the companion, {archive}, with every notebook.",
        "repository": "Its sources: {repository}",
    },
    "vi": {
        "version": "Phiên bản {version}, {date}",
        "downloads": "Mọi chương đều chạy được trên máy của bạn: trang đầu của bản web có thư viện, "
                     "{wheel}, và sách đồng hành, {archive}, với mọi notebook.",
        "repository": "Mã nguồn: {repository}",
    },
}
#: Elements wider than the text column in the printed layout (MathJax's invisible copy for screen
#: readers aside), with the page of the site they are on; print.css should leave none.
WIDE = r"""() => {
    const column = document.querySelector('article').getBoundingClientRect();
    const wide = (e) => { const r = e.getBoundingClientRect(); return r.width > 0 && r.right > column.right + 2; };
    const starts = [...document.querySelectorAll('span[id^="document-"]')];
    return [...document.querySelectorAll('article *')]
        .filter(e => wide(e) && !wide(e.parentElement) && !e.closest('mjx-assistive-mml'))
        .map(e => {
            const start = starts.filter(s => s.compareDocumentPosition(e) & Node.DOCUMENT_POSITION_FOLLOWING).pop();
            return `${start ? start.id.slice(9) : 'front'}: ${e.tagName.toLowerCase()} `
                + `${Math.round(e.getBoundingClientRect().right - column.right)} px too wide, `
                + `"${(e.textContent || '').trim().slice(0, 60)}"`;
        });
}"""
#: Marks the blocks to keep on one page (class pdf-keep, print.css): a cell, or else its input and its
#: output, a table, an admonition, no taller than the limit given in CSS pixels.
KEEP = r"""(limit) => {
    const short = (e) => e.getBoundingClientRect().height <= limit;
    const keep = [];
    document.querySelectorAll('article div.cell').forEach(cell => {
        if (short(cell)) keep.push(cell);
        else keep.push(...[...cell.querySelectorAll(':scope > div.cell_input, :scope > div.cell_output')]
            .filter(short));
    });
    keep.push(...[...document.querySelectorAll('article table, article div.admonition, article div.proof')]
        .filter(short));
    keep.forEach(e => e.classList.add('pdf-keep'));
    return keep.length;
}"""
#: The tallest block kept on one page: 40 % of the text's height (297 mm less 36 mm of margins) in CSS px.
KEEP_PX = 0.4 * (297 - 36) / 25.4 * 96
#: The text of every heading that is printed (so in the bookmarks), in order: the headings' links
#: left out, and each formula written out from MathJax's MathML ("φ̇0 = 1" for \dot\varphi_0 = 1).
HEADINGS = r"""() => {
    const mathText = (node) => {
        if (node.nodeType === Node.TEXT_NODE) return node.textContent;
        if (node.nodeType !== Node.ELEMENT_NODE) return '';
        const tag = node.tagName.toLowerCase(), text = node.textContent.trim();
        if (tag === 'mo') return /^[=<>≤≥≈±+−×]$/.test(text) ? ` ${text} ` : (text === ',' ? ', ' : text);
        const parts = [...node.childNodes].map(mathText);
        if (tag === 'mover' && node.children.length === 2) {
            const accents = {'˙': '\u0307', '¨': '\u0308', '.': '\u0307', '^': '\u0302', '~': '\u0303'};
            const accent = accents[node.children[1].textContent.trim()];
            if (accent) return parts[0] + accent;
        }
        return parts.join('');
    };
    const plain = (heading) => {
        const copy = heading.cloneNode(true);
        copy.querySelectorAll('.headerlink').forEach(e => e.remove());
        copy.querySelectorAll('mjx-container').forEach(container => {
            const math = container.querySelector('mjx-assistive-mml math');
            container.replaceWith(document.createTextNode(math ? mathText(math) : ''));
        });
        return copy.textContent.replace(/\s+/g, ' ').trim();
    };
    return [...document.querySelectorAll('h1, h2, h3, h4, h5, h6')]
        .filter(h => h.getClientRects().length > 0).map(plain);
}"""
HEADER = ('<div style="font-size:7.5pt; color:#666; width:100%; margin:0 15mm; '
          'white-space:nowrap; overflow:hidden; text-overflow:ellipsis;"><span class="title"></span></div>')
FOOTER = ('<div style="font-size:8pt; color:#444; width:100%; margin:0 15mm; text-align:center;">'
          '<span class="pageNumber"></span> / <span class="totalPages"></span></div>')
#: How many times the book is printed at most, to get the contents' page numbers right.
MAX_PRINTS = 3


class PrintError(RuntimeError):
    """The page could not be printed as it should be (a failed load, a missing tool, an unknown target)."""


def root_document(toc=ROOT / "_toc.yml"):
    """The book's root document (``root`` in ``_toc.yml``), e.g. ``"book/intro"``."""
    import yaml

    return yaml.safe_load(Path(toc).read_text(encoding="utf-8"))["root"]


@contextlib.contextmanager
def serve(folder, root_page):
    """Serve ``folder`` on 127.0.0.1, with ``root_page`` (a file in it) at ``/``; yields the URL of ``/``.

    Sphinx writes the single page's links relative to the build's top folder, wherever the root
    document lies (``book/intro.html`` links ``_static/...``), so the page is served from the top.
    """
    page_file = "/" + Path(root_page).as_posix()

    class Handler(http.server.SimpleHTTPRequestHandler):
        def translate_path(self, path):
            return super().translate_path(page_file if path.split("?")[0] == "/" else path)

        def log_message(self, *args):
            pass

    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Handler, directory=str(folder)))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/"
    finally:
        server.shutdown()
        server.server_close()


def open_book(browser, url, timeout_ms=300_000):
    """The single page in a new tab, with every formula typeset and every Bokeh figure drawn.

    Raises
    ------
    PrintError
        On a console error, an uncaught page error or a failed request (what the site test
        calls a fault), or when the math or the figures are not done within ``timeout_ms``.
    """
    page = browser.new_page(viewport={"width": COLUMN_PX, "height": 1000}, device_scale_factor=2)
    page.set_default_timeout(timeout_ms)
    problems = []
    page.on("pageerror", lambda error: problems.append(f"page error: {error}"))
    page.on("response", lambda response: response.status >= 400
            and not response.url.endswith(NOT_WRITTEN) and problems.append(f"HTTP {response.status}: {response.url}"))
    page.on("requestfailed", lambda request: "ERR_ABORTED" in (request.failure or "")
            or problems.append(f"request failed: {request.url} ({request.failure})"))
    page.goto(url, wait_until="networkidle")
    if page.locator("div.math, span.math").count():
        page.wait_for_function("() => window.MathJax && MathJax.startup && MathJax.startup.promise")
        page.evaluate("() => MathJax.startup.promise")
    wait_for_bokeh(page)
    faults = page.evaluate("""() => ({
        math: document.querySelectorAll('div.math, span.math').length,
        typeset: document.querySelectorAll('div.math mjx-container, span.math mjx-container').length,
        errors: document.querySelectorAll('mjx-merror').length,
        images: [...document.querySelectorAll('article img')].filter(i => !(i.complete && i.naturalWidth > 0))
                .map(i => (i.getAttribute('src') || '').slice(0, 80)),
    })""")
    if faults["typeset"] != faults["math"] or faults["errors"]:
        problems.append(f"math: {faults['typeset']} of {faults['math']} formulas typeset, "
                        f"{faults['errors']} in error")
    problems += [f"image not loaded: {src}" for src in faults["images"]]
    if problems:
        raise PrintError("the single page did not load cleanly:\n  " + "\n  ".join(problems))
    return page


def wait_for_bokeh(page):
    """Wait until BokehJS has drawn every interactive figure (each ``div.closedloop-bokeh``) and is idle."""
    page.wait_for_function("""() => {
        const wanted = document.querySelectorAll('div.closedloop-bokeh').length;
        if (!wanted) return true;
        return window.Bokeh && Bokeh.documents.length >= wanted && Bokeh.documents.every(d => d.is_idle);
    }""")
    page.evaluate("() => new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")


#: Pages of the site that the printed book leaves out besides the rubrics: the library reference, the
#: docstrings that ``help()`` shows (and which name environment variables, ``$CLOSEDLOOP_CACHE_DIR``).
SITE_ONLY = ("book/reference",)


def left_out():
    """Every page the PDF leaves out: those for instructors only, and :data:`SITE_ONLY`."""
    return [*instructors_only(), *SITE_ONLY]


def instructors_only():
    """The pages the PDF leaves out, as the course edition does (book/_ext/companion.py)."""
    sys.path.insert(0, str(ROOT / "book" / "_ext"))
    from companion import INSTRUCTORS_ONLY

    return list(INSTRUCTORS_ONLY)


def texts_for(page):
    """The notes in the page's language (``<html lang>``); English, said so, for a language without them;
    and the pages to leave out (``omit``)."""
    language = (page.evaluate("() => document.documentElement.lang") or "en").split("-")[0]
    if language not in TEXTS:
        print(f"print_pdf: no notes in language {language!r} in TEXTS; the English ones are used", file=sys.stderr)
    return {**TEXTS.get(language, TEXTS["en"]), **TITLE_PAGE.get(language, TITLE_PAGE["en"]),
            "omit": left_out()}


def prepare(page):
    """Make the page a book (``prepare.js``, then ``print.css`` and print media); returns what changed.

    Raises
    ------
    PrintError
        If anything is wider than the printed text column (it would be cut off).
    """
    counts = page.evaluate((HERE / "prepare.js").read_text(encoding="utf-8"), texts_for(page))
    page.add_style_tag(content=(HERE / "print.css").read_text(encoding="utf-8"))
    page.emulate_media(media="print")
    wait_for_bokeh(page)              # the figures are drawn again at the printed layout
    counts["keptWhole"] = page.evaluate(KEEP, KEEP_PX)
    wide = page.evaluate(WIDE)
    if wide:
        raise PrintError("content wider than the printed column (print.css should wrap it):\n  " + "\n  ".join(wide))
    return counts


def print_once(page, path):
    """One print of ``page`` to ``path``: A4, header and footer, bookmarks from the headings, tagged."""
    page.pdf(path=str(path), print_background=True, display_header_footer=True, header_template=HEADER,
             footer_template=FOOTER, outline=True, tagged=True, **PAPER)


def destinations(pdf):
    """``{name: page}`` of the named destinations in ``pdf`` (``pdfinfo -dests``; pages from 1).

    Chromium writes one for every element that a link of the page points to.
    """
    if shutil.which("pdfinfo") is None:
        raise PrintError("pdfinfo not found: install Debian's poppler-utils (make pdf does)")
    listing = subprocess.run(["pdfinfo", "-dests", str(pdf)], check=True, capture_output=True, text=True).stdout
    found = {}
    for line in listing.splitlines():
        match = re.match(r'^\s*(\d+)\s+\[.*\]\s+"(.*)"\s*$', line)
        if match:
            found.setdefault(match.group(2), int(match.group(1)))
    return found


def _pdf_text(text):
    """``text`` as a PDF text string: UTF-16BE with its byte-order mark, in hex."""
    return b"<" + ("\ufeff" + text).encode("utf-16-be").hex().upper().encode("ascii") + b">"


def retitle_bookmarks(pdf, titles):
    """Give the bookmarks of ``pdf`` the ``titles`` (one per heading, in order), as an incremental update.

    Chromium names each bookmark after the text it painted for the heading: a heading at the top of
    a page comes out twice ("InterpretingInterpreting"), a wrapped one without the space at the
    wrap, its math left out ("Case 1: ,  rad/s"). The bookmarks are Chromium's (pages, nesting);
    only their titles are written again, as new versions of those objects appended to the file
    with their own cross-reference section (PDF 1.4, 3.4.5), so nothing before is moved.

    Raises
    ------
    PrintError
        If the file has not one bookmark per title.
    """
    data = Path(pdf).read_bytes()
    title = rb"/Title\s*(?:\((?:\\.|[^\\)])*\)|<[0-9A-Fa-f]*>)"         # a literal or a hex string
    items = {int(m.group(1)): m.group(2)
             for m in re.finditer(rb"(\d+) 0 obj\s*<<(" + title + rb".*?)>>\s*endobj", data, re.S)}
    root = re.search(rb"<</Type /Outlines\s*/First (\d+) 0 R", data)
    order, stack = [], [int(root.group(1))] if root else []
    while stack:                                  # the bookmarks in order: each one, then its children
        number = stack.pop()
        order.append(number)
        body = items[number]
        following = re.search(rb"/Next (\d+) 0 R", body)
        first = re.search(rb"/First (\d+) 0 R", body)
        stack += [int(m.group(1)) for m in (following, first) if m]
    if len(order) != len(titles):
        raise PrintError(f"{len(order)} bookmarks in {pdf} for {len(titles)} headings; cannot name them")
    trailer = re.findall(rb"trailer\s*<<(.*?)>>\s*startxref\s*(\d+)", data, re.S)[-1]
    fields = dict(re.findall(rb"/(Size|Root|Info) (\d+(?: 0 R)?)", trailer[0]))
    update, offsets = bytearray(b"\n"), {}
    for number, text in zip(order, titles):
        offsets[number] = len(data) + len(update)
        body = re.sub(b"^" + title, lambda m: b"/Title " + _pdf_text(text), items[number], count=1)
        update += b"%d 0 obj\n<<%s>>\nendobj\n" % (number, body)
    xref = len(data) + len(update)
    update += b"xref\n" + b"".join(b"%d 1\n%010d 00000 n \n" % (n, offsets[n]) for n in sorted(offsets))
    update += b"trailer\n<</Size %s /Root %s /Info %s /Prev %s>>\nstartxref\n%d\n%%%%EOF\n" % (
        fields[b"Size"], fields[b"Root"], fields[b"Info"], trailer[1], xref)
    Path(pdf).write_bytes(data + bytes(update))
    return len(order)


def number_contents(page, pages):
    """Write each contents entry's page from ``pages`` (``{target id: page}``); returns the numbers written.

    Raises
    ------
    PrintError
        If an entry's target has no page.
    """
    targets = page.evaluate("() => [...document.querySelectorAll('.pdf-toc-page')].map(e => e.dataset.target)")
    missing = [target for target in targets if target not in pages]
    if missing:
        raise PrintError(f"no page found for the contents entries {missing}")
    numbers = {target: pages[target] for target in targets}
    page.evaluate("""(numbers) => document.querySelectorAll('.pdf-toc-page')
                         .forEach(e => { e.textContent = String(numbers[e.dataset.target]); })""", numbers)
    return numbers


def print_book(html_folder, output, root=None):
    """Print the single-page build in ``html_folder`` to ``output``; returns a report (dict).

    Parameters
    ----------
    html_folder : path
        Output folder of ``jupyter-book build . --builder singlehtml``.
    output : path
        The PDF to write (its folder is created).
    root : str, optional
        The root document, whose page is the single page; default: ``root`` of ``_toc.yml``.
    """
    from playwright.sync_api import sync_playwright

    html_folder, output = Path(html_folder), Path(output)
    root_page = f"{root or root_document()}.html"
    if not (html_folder / root_page).exists():
        raise PrintError(f"no single-page build at {html_folder / root_page}: run "
                         "`jupyter-book build . --builder singlehtml` first (make pdf does)")
    browser_path = chromium()
    if not Path(browser_path).exists():
        raise PrintError(f"Chromium not found at {browser_path}: install Debian's chromium-headless-shell package "
                         "(make pdf does)")
    output.parent.mkdir(parents=True, exist_ok=True)
    draft = output.with_name(output.stem + ".draft.pdf")
    report = {"prints": 0}
    started = time.perf_counter()
    with serve(html_folder, root_page) as url, sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=browser_path, args=CHROMIUM_FLAGS)
        try:
            page = open_book(browser, url)
            report["changed"] = prepare(page)
            report["load_s"] = time.perf_counter() - started
            numbers = None
            while report["prints"] < MAX_PRINTS:
                print_once(page, draft)
                report["prints"] += 1
                pages = destinations(draft)
                if numbers is not None and all(pages.get(t) == n for t, n in numbers.items()):
                    break                              # the numbers printed are the pages: done
                numbers = number_contents(page, pages)
            else:
                raise PrintError(f"the contents' page numbers still moved after {MAX_PRINTS} prints")
            report["bookmarks"] = retitle_bookmarks(draft, page.evaluate(HEADINGS))
        finally:
            browser.close()
    draft.replace(output)
    report["seconds"] = time.perf_counter() - started
    report["pages"] = int(re.search(r"^Pages:\s+(\d+)", subprocess.run(
        ["pdfinfo", str(output)], check=True, capture_output=True, text=True).stdout, re.M).group(1))
    return report


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("html", help="the single-page build's folder, e.g. _build/singlehtml")
    parser.add_argument("output", help="the PDF to write, e.g. _build/pdf/closedloop.pdf")
    parser.add_argument("--root", help="the root document (default: root of _toc.yml)")
    args = parser.parse_args(argv)
    try:
        report = print_book(args.html, args.output, args.root)
    except PrintError as error:
        print(f"print_pdf: {error}", file=sys.stderr)
        return 1
    changed = ", ".join(f"{key} {value}" for key, value in report["changed"].items())
    print(f"{args.output}: {report['pages']} pages, printed {report['prints']} times in {report['seconds']:.0f} s "
          f"(page ready in {report['load_s']:.0f} s); {changed}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
