"""The book as a PDF (``make pdf``, ``book/print/print_pdf.py``), read back with Debian's poppler-utils.

The PDF is made once per session after the book (the ``built_pdf`` fixture of conftest.py) and read
with ``pdfinfo``, ``pdftotext``, ``pdfimages`` and ``pdftohtml -xml`` (its bookmarks). Everything the
tests expect is read from the sources or from the built site, never typed here:

- its length: every page of the site starts a printed page (but the rubrics, for instructors only, and
  the library reference, which is the docstrings), and
  the pages hold text;
- its title page: the title, the authors, the version and its date, and the names of the wheel and
  the archive the web edition offers;
- every page's title (the first heading of its source) in the text, the chapters with their number,
  and the contents' page numbers pointing at those titles;
- numbered like the site: every numbered heading of the built site's chapters is a bookmark, with
  the same number (and the same text where it has no formula);
- no exercise solution: no sentence of a solution's prose, no line of its code; each exercise's
  statement is there (the same search finds them, so the first check can fail);
- no TeX left: no ``$``, and none of the TeX commands the sources' formulas use;
- no number glued into the prose ("7e-08") broken across two lines at its exponent's sign;
- the bibliography: every entry of ``book/references.bib``;
- every page with the book's title in its header and "page / pages" in its footer;
- each animation as a still with its note naming its chapter, each interactive figure drawn.

A few pages are rendered to PNG in ``_build/pdf/pages/`` (title, contents, a chapter's opening,
display math, a figure, an animation's still, an interactive figure, an exercise page, the
bibliography), to be looked at. Skipped, and says so, when Chromium or poppler-utils is missing
(the ``built_pdf`` fixture).
With ``CLOSEDLOOP_SITE_BUILT=1`` the tests read the ``_build/pdf`` already there.
"""

import html
import re
import subprocess
from functools import lru_cache
from pathlib import Path

import pytest
import yaml
from print_pdf import SITE_ONLY, TEXTS, TITLE_PAGE, instructors_only, left_out

from ._toc import toc_documents as toc_pages_and_numbering

ROOT = Path(__file__).resolve().parents[1]
PAGES_OUT = ROOT / "_build" / "pdf" / "pages"
#: Text an animation's and an interactive figure's note begin with (print_pdf.TEXTS, English).
NOTES = {kind: text.split("{chapter}")[0] for kind, text in TEXTS["en"].items()}


def toc_documents():
    """[(docname, numbered)] of every page the PDF prints: the site's, without the pages for instructors
    only (the rubrics), which the PDF leaves out as the course edition does, and the library reference."""
    return [(docname, numbered) for docname, numbered in toc_pages_and_numbering() if docname not in left_out()]


def run(*command):
    return subprocess.run(command, check=True, capture_output=True, text=True).stdout


def pages_with_pictures(pdf):
    """The pages that hold a picture: an image (not a mask) at least 200 pixels wide (pdfimages -list)."""
    rows = [row.split() for row in run("pdfimages", "-list", str(pdf)).splitlines()[2:]]
    return {int(row[0]) for row in rows if row[2] == "image" and int(row[3]) >= 200}


# --- what the sources say ------------------------------------------------------------------
def source_title(docname):
    """The first heading of a page's source, as the site prints it (straight quotes made curly)."""
    text = (ROOT / f"{docname}.md").read_text(encoding="utf-8")
    title = re.search(r"^# (.+)$", text, flags=re.M).group(1).strip()
    return title.replace("'", "\u2019")


def chapter_titles():
    """[(number, title)] of the numbered chapters, numbered through the toc as the site numbers them."""
    numbered = [docname for docname, is_numbered in toc_documents() if is_numbered]
    return [(str(index), source_title(docname)) for index, docname in enumerate(numbered, 1)]


FENCE = re.compile(r"^(?P<fence>`{3,}|:{3,})\s*\{(?P<name>[\w-]+)\}")


def exercise_parts(text):
    """(statements, solutions): the source lines of every exercise statement and of every solution."""
    lines = text.splitlines()
    statements, solutions, i = [], [], 0
    while i < len(lines):
        match = FENCE.match(lines[i])
        name = match.group("name") if match else None
        if name in ("exercise", "solution"):
            j = i + 1
            while j < len(lines) and lines[j].strip() != match.group("fence"):
                j += 1
            (statements if name == "exercise" else solutions).append(lines[i + 1:j])
            i = j + 1
        elif name == "solution-start":
            j = i + 1
            while j < len(lines) and lines[j].strip() != match.group("fence"):
                j += 1
            k = j + 1
            while k < len(lines) and not re.match(r"^[`:]{3,}\s*\{solution-end\}", lines[k]):
                k += 1
            solutions.append(lines[j + 1:k])
            i = k + 1
        else:
            i += 1
    return statements, solutions


#: Characters of MyST markup or math: a sentence holding one prints differently from its source.
MARKUP = set("$`{}[]*_|<>#=\\~")


def plain_sentences(lines):
    """The sentences of ``lines`` (prose, no code cell) that print exactly as written, 40 characters or more."""
    prose, in_code = [], False
    for line in lines:
        if FENCE.match(line) or line.strip().startswith("```"):
            in_code = not in_code if line.strip().startswith("```") else in_code
            continue
        if not in_code and not line.startswith(":"):
            prose.append(line)
    text = " ".join(" ".join(prose).split())
    return [s for s in re.split(r"(?<=[.?!])\s+", text)
            if len(s) >= 40 and not MARKUP & set(s) and "--" not in s and "..." not in s]


def code_lines(lines):
    """The code lines of the code cells in ``lines`` (markers and short lines aside)."""
    out, inside = [], False
    for line in lines:
        if line.startswith("```"):
            inside = line.startswith("```{code-cell}")
            continue
        stripped = line.strip()
        if inside and len(stripped) > 20 and not stripped.startswith("#") and not stripped.startswith(":"):
            out.append(stripped)
    return out


def typographic(text):
    """``text`` with the quotes Sphinx prints (curly) made straight, and its whitespace single."""
    for curly, straight in (("\u2019", "'"), ("\u2018", "'"), ("\u201c", '"'), ("\u201d", '"')):
        text = text.replace(curly, straight)
    return " ".join(text.split())


@lru_cache(maxsize=None)
def sources():
    """{docname: source text} of every page of the book."""
    return {docname: (ROOT / f"{docname}.md").read_text(encoding="utf-8") for docname, _ in toc_documents()}


def tex_commands():
    """Every TeX command (``\\frac``, ``\\dot``, ...) used in the formulas of the sources."""
    found = set()
    for text in sources().values():
        math = re.findall(r"\$\$(.+?)\$\$|\$([^$\n]+)\$", text, flags=re.S)
        math += [(block, "") for block in re.findall(r"```\{math\}(.*?)```", text, flags=re.S)]
        for display, inline in math:
            found.update(re.findall(r"\\[A-Za-z]{2,}", display + inline))
    return found


def bibliography_titles():
    """The first words of every title in book/references.bib (braces and TeX dashes as printed)."""
    bib = (ROOT / "book" / "references.bib").read_text(encoding="utf-8")
    titles = []
    for start in re.finditer(r"\btitle\s*=\s*\{", bib):
        depth, i = 1, start.end()
        while depth:
            depth += {"{": 1, "}": -1}.get(bib[i], 0)
            i += 1
        title = bib[start.end():i - 1].replace("{", "").replace("}", "").replace("--", "\u2013")
        titles.append(" ".join(title.split()[:5]))
    return titles


# --- what the PDF says ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def pdf(built_pdf):
    return built_pdf


@pytest.fixture(scope="module")
def pages(pdf):
    """The text of every page, as pdftotext reads it (pages split at form feeds)."""
    return run("pdftotext", str(pdf), "-").split("\f")[:-1]


def without_margins(page, number, count):
    """A page's text without its header (the book's title) and its footer ("page / pages")."""
    title = yaml.safe_load((ROOT / "_config.yml").read_text())["title"]
    lines = page.splitlines()
    header = lines.index(title) if title in lines else None
    footer = f"{number} / {count}"
    return "\n".join(line for k, line in enumerate(lines) if k != header and line != footer)


@pytest.fixture(scope="module")
def body(pdf):
    """The whole text without the pages' headers and footers, whitespace single, quotes straight.

    Read in the order it is drawn (``pdftotext -raw``), where a line of prose stays whole: in
    reading order a formula's superscript can land between the words of the line below it.
    """
    pages = run("pdftotext", "-raw", str(pdf), "-").split("\f")[:-1]
    return typographic(" ".join(without_margins(page, k, len(pages)) for k, page in enumerate(pages, 1)))


@pytest.fixture(scope="module")
def starts(pdf):
    """{docname: first page} of every page of the site (its link target, ``document-<docname>``)."""
    listing = run("pdfinfo", "-dests", str(pdf))
    return {m.group(2): int(m.group(1))
            for m in re.finditer(r'^\s*(\d+)\s+\[.*\]\s+"document-(.+)"\s*$', listing, re.M)}


@pytest.fixture(scope="module")
def bookmarks(pdf):
    """[(page, title)] of the PDF's bookmarks, in order."""
    xml = run("pdftohtml", "-xml", "-i", "-stdout", "-q", "-f", "1", "-l", "1", str(pdf))
    return [(int(page), html.unescape(title)) for page, title in re.findall(r'<item page="(\d+)">(.*?)</item>', xml)]


def test_page_count(pdf, pages, starts):
    count = int(re.search(r"^Pages:\s+(\d+)", run("pdfinfo", str(pdf)), re.M).group(1))
    assert count == len(pages)
    documents = toc_documents()
    assert sorted(starts) == sorted(docname for docname, _ in documents), "not every page of the site starts a page"
    # a title page, the contents and the root page come first; every page of the site starts a new page
    assert count >= 3 + len(documents) and min(starts.values()) >= 4
    assert sorted(starts.values()) == [starts[d] for d, _ in documents], "the pages are not in the site's order"
    # no page is empty; on average a page holds at least 20 lines (a bound far below the book's ~50)
    lines = [len([line for line in without_margins(page, k, count).splitlines() if line.strip()])
             for k, page in enumerate(pages, 1)]
    images = pages_with_pictures(pdf)
    assert [k for k, n in enumerate(lines, 1) if n == 0 and k not in images] == []
    assert count <= 3 + len(documents) + sum(lines) / 20


def test_every_page_title_is_in_the_pdf(body):
    missing = [source_title(docname) for docname, _ in toc_documents()
               if typographic(source_title(docname)) not in body]
    assert missing == []
    # the chapters numbered as on the site: "6. The four cases"
    assert [f"{n}. {t}" for n, t in chapter_titles() if typographic(f"{n}. {t}") not in body] == []


def test_the_contents_give_each_page_where_it_starts(pdf, pages, starts):
    contents = typographic(run("pdftotext", "-layout", "-f", "2", "-l", "2", str(pdf), "-"))
    for docname, numbered in toc_documents():
        title = typographic(source_title(docname))
        listed = re.search(r"(?:\d+\. )?" + re.escape(title) + r"\s*(\d+)", contents)
        assert listed, f"{title!r} is not in the contents"
        assert int(listed.group(1)) == starts[docname], f"{title!r}: the contents say page {listed.group(1)}"
        assert title in typographic(pages[starts[docname] - 1]), f"{title!r} not on page {starts[docname]}"


def site_headings(html_folder):
    """[(number, text or None)] of every numbered heading of the site's chapters (None: it holds a formula)."""
    found = []
    for docname, numbered in toc_documents():
        if not numbered:
            continue
        page = (html_folder / f"{docname}.html").read_text(encoding="utf-8")
        heading = r'<h[1-6]><span class="section-number">([\d.]+) </span>(.*?)<a class="headerlink"'
        for number, inner in re.findall(heading, page, flags=re.S):
            text = html.unescape(re.sub(r"<[^>]+>", "", inner))
            found.append((number, None if "\\(" in text else " ".join(text.split())))
    return found


def test_numbered_like_the_site(built_site, bookmarks):
    expected = site_headings(built_site)
    assert len(expected) > len(chapter_titles()), "no numbered sections found on the site"
    printed = {}
    for _, title in bookmarks:
        match = re.match(r"^([\d.]+\.) (.*)$", title)
        if match:
            printed[match.group(1)] = match.group(2)
    assert [number for number, _ in expected if number not in printed] == []
    assert [(n, t, printed[n]) for n, t in expected if t is not None and printed[n] != t] == []
    assert len(printed) == len(expected), "the PDF numbers headings that the site does not"


def test_bookmarks(bookmarks, starts):
    """Every page of the site is a bookmark at its first page, the chapters numbered; no title doubled.

    (Chromium names a bookmark after the text it painted, and wrote "InterpretingInterpreting" for a
    heading at the top of a page; print_pdf.retitle_bookmarks names them after the headings.)
    """
    numbers = dict(zip([d for d, numbered in toc_documents() if numbered], (n for n, _ in chapter_titles())))
    for docname, _ in toc_documents():
        title = source_title(docname)
        expected = f"{numbers[docname]}. {title}" if docname in numbers else title
        assert (starts[docname], expected) in bookmarks, f"no bookmark {expected!r} at page {starts[docname]}"
    doubled = [t for _, t in bookmarks if len(t) % 2 == 0 and t[:len(t) // 2] == t[len(t) // 2:]]
    assert doubled == []


def exercise_titles(text):
    """The printed title of every exercise in a source.

    ``{exercise} 6.4: A fifth start`` prints as "Exercise 6.4 (A fifth start)" (book/_ext/exercise_titles.py).
    """
    return [f"Exercise {m.group(1)} ({m.group(2).strip()})" for m in
            re.finditer(r"^[`:]{3,}\{exercise(?:-start)?\}\s*(\d+(?:\.\d+)+):\s*(.+)$", text, re.M)]


def test_no_solution_and_every_statement(body):
    everything_but_solutions = []
    for text in sources().values():
        for part in exercise_parts(text)[1]:
            text = text.replace("\n".join(part), "")
        everything_but_solutions.append(text)
    outside = typographic("\n".join(everything_but_solutions))   # what the book prints outside solutions
    pages_with_exercises = 0
    for docname, text in sources().items():
        asked, solved = exercise_parts(text)
        if not asked:
            continue
        pages_with_exercises += 1
        titles = [t for t in exercise_titles(text) if not MARKUP & set(t)]   # a title with a formula prints otherwise
        statements = [s for part in asked for s in plain_sentences(part)]
        # a solution's sentence or code line that is printed outside solutions too would prove nothing
        solution = [s for part in solved for s in plain_sentences(part) + code_lines(part)
                    if typographic(s) not in outside]
        assert len(exercise_titles(text)) == len(asked) and solution, \
            f"{docname}: no exercise or solution found (the test would prove nothing)"
        assert [t for t in titles + statements if typographic(t) not in body] == [], f"{docname}: exercise missing"
        assert [s for s in solution if typographic(s) in body] == [], f"{docname}: solution in the PDF"
    assert pages_with_exercises >= len([d for d, _ in toc_documents() if d.startswith("exercises/")])
    assert "Solution to" not in body


def test_no_tex_is_left(pages):
    text = "\n".join(pages)
    commands = tex_commands()
    assert {"\\frac", "\\dot", "\\begin"} <= commands, "the sources' formulas were not found"
    assert "$" not in text
    assert sorted(c for c in commands if re.search(re.escape(c) + r"(?![A-Za-z])", text)) == []


def test_no_number_is_broken_at_its_exponent(pdf):
    """A number glued into the prose ("7e-08") is one word: a line may not end at its exponent's sign
    (Chromium breaks after a hyphen-minus unless the book's CSS keeps the number whole)."""
    lines = run("pdftotext", "-raw", str(pdf), "-").splitlines()      # in drawing order: lines whole
    assert sum(len(re.findall(r"\b\d(?:\.\d+)?e[-+]\d\d\b", line)) for line in lines) > 5, \
        "no number of the form 1.0e-10 found in the PDF's text"
    assert [line[-40:] for line in lines if re.search(r"\b\d(?:\.\d+)?e[-+]$", line.rstrip())] == []


def test_the_bibliography(body, pages, starts):
    titles = bibliography_titles()
    assert len(titles) == len(re.findall(r"^@\w+\{", (ROOT / "book" / "references.bib").read_text(), re.M))
    following = min(page for page in starts.values() if page > starts["book/bibliography"])
    bibliography = typographic(" ".join(pages[starts["book/bibliography"] - 1:following - 1]))
    assert [t for t in titles if typographic(t) not in bibliography] == []


def test_headers_and_footers(pdf, pages):
    """The text in each page's top and bottom margins (pdftotext -bbox) is the title and "page / pages"."""
    title = yaml.safe_load((ROOT / "_config.yml").read_text())["title"]
    margin = 18 / 25.4 * 72                                   # print_pdf.PAPER's 18 mm, in points
    boxes = run("pdftotext", "-bbox", str(pdf), "-")
    found = re.findall(r'<page width="([\d.]+)" height="([\d.]+)">(.*?)</page>', boxes, flags=re.S)
    assert len(found) == len(pages)
    for number, (_, height, words) in enumerate(found, 1):
        words = [(float(y0), float(y1), html.unescape(w)) for y0, y1, w in
                 re.findall(r'<word xMin="[\d.]+" yMin="([\d.]+)" xMax="[\d.]+" yMax="([\d.]+)">(.*?)</word>', words)]
        top = " ".join(w for y0, y1, w in words if y1 < margin)
        bottom = " ".join(w for y0, y1, w in words if y0 > float(height) - margin)
        assert (top, bottom) == (title, f"{number} / {len(pages)}"), f"page {number}"


def test_animations_are_stills_with_a_note(pdf, pages, starts):
    calls = {docname: len(re.findall(r"^\s+animate_(?:slider_crank|four_bar)\(", text, re.M))
             for docname, text in sources().items() if docname.startswith("chapters/")}
    numbers = {docname: n for (n, _), docname in zip(chapter_titles(), [d for d, k in toc_documents() if k])}
    notes = [(k, m.group(1)) for k, page in enumerate(pages, 1)
             for m in re.finditer(re.escape(NOTES["animation"]) + r"(\d+)", " ".join(page.split()))]
    expected = sorted(numbers[docname] for docname, count in calls.items() for _ in range(count))
    assert expected and sorted(chapter for _, chapter in notes) == expected
    images = pages_with_pictures(pdf)
    assert [k for k, _ in notes if k not in images] == [], "an animation's note without its still"


def test_interactive_figures_are_drawn(pdf, pages):
    calls = sum(len(re.findall(r"^display\(interactive_\w+\(", text, re.M)) for text in sources().values())
    noted = [k for k, page in enumerate(pages, 1) if NOTES["interactive"] in " ".join(page.split())]
    assert calls and len(noted) == calls
    images = pages_with_pictures(pdf)
    assert [k for k in noted if k not in images] == [], "an interactive figure's note, and no figure drawn"


def test_pages_to_look_at(pdf, pages, starts):
    """Renders the pages a reader should look at to _build/pdf/pages/*.png; each one must show something."""
    from PIL import Image

    images = pages_with_pictures(pdf)
    chapter6 = range(starts["chapters/06-four-cases"], starts["chapters/07-conclusions"])
    first = lambda found: next(iter(found), None)                                   # noqa: E731
    noted = lambda kind, k: NOTES[kind] in " ".join(pages[k - 1].split())            # noqa: E731
    chosen = {
        "title": 1,
        "contents": 2,
        "chapter-opening": starts["chapters/01-closed-loop-systems"],
        "display-math": first(k for k in range(starts["chapters/02-lagrange-multipliers"], len(pages) + 1)
                              if re.search(r"^\(\d+\)$", pages[k - 1], re.M)),
        "figure": first(k for k in chapter6 if k in images and not noted("animation", k)),
        "animation": first(k for k in chapter6 if noted("animation", k)),
        "interactive": first(k for k in range(1, len(pages) + 1) if noted("interactive", k)),
        "exercise-page": starts["exercises/06-four-cases"],
        "bibliography": starts["book/bibliography"],
    }
    assert None not in chosen.values(), chosen
    PAGES_OUT.mkdir(parents=True, exist_ok=True)
    for old in PAGES_OUT.glob("*.png"):
        old.unlink()
    for name, page in chosen.items():
        target = PAGES_OUT / f"{page:03d}-{name}"
        run("pdftoppm", "-r", "80", "-png", "-singlefile", "-f", str(page), "-l", str(page), str(pdf), str(target))
        grey = Image.open(f"{target}.png").convert("L")
        low, high = grey.getextrema()
        assert low < 100 and high > 200, f"page {page} ({name}) renders blank"


def test_the_vietnamese_edition_is_printed_too(pdf, pages):
    """``make pdf`` prints the Vietnamese edition (``closedloop.vi.pdf``) from its own single-page build:
    the same book in about as many pages, every page's title in its translation (the catalogue's),
    its notes in Vietnamese, and no TeX left."""
    from babel.messages.pofile import read_po

    vi = pdf.with_name("closedloop.vi.pdf")
    assert vi.exists(), f"no {vi}"
    vi_pages = run("pdftotext", str(vi), "-").split("\f")[:-1]
    assert 0.85 * len(pages) <= len(vi_pages) <= 1.3 * len(pages), (len(pages), len(vi_pages))
    text = typographic(" ".join(run("pdftotext", "-raw", str(vi), "-").split()))
    missing = []
    for docname, _ in toc_documents():
        raw = re.search(r"^# (.+)$", (ROOT / f"{docname}.md").read_text(encoding="utf-8"), re.M).group(1).strip()
        with open(ROOT / "locales" / "vi" / "LC_MESSAGES" / f"{docname}.po", "rb") as handle:
            title = read_po(handle).get(raw).string
        if typographic(title.replace("'", "\u2019")) not in text:
            missing.append(title)
    assert missing == [], "titles of the Vietnamese edition not in its PDF"
    for kind, note in TEXTS["vi"].items():
        if NOTES[kind] in " ".join(pages):                  # the English PDF has this note, so must this one
            assert typographic(note.split("{chapter}")[0]) in text, kind
    assert "$" not in text and "\\frac" not in text


def test_both_pdfs_print_the_same_display_equations(pdf):
    """The single pages that ``make pdf`` prints show, edition for edition, the same display equations
    (as tests/test_translations.py checks page by page on the site): none lost to ``::``."""
    from print_pdf import root_document

    from .test_translations import translations

    page = f"{root_document()}.html"                     # the single page: the root document's
    english = translations.display_equations((ROOT / "_build" / "singlehtml" / page).read_text())
    vietnamese = translations.display_equations((ROOT / "_build" / "vi" / "_build" / "singlehtml" / page).read_text())
    assert english and not [tex for tex in vietnamese if tex in ("", "::")]
    assert english == vietnamese


def test_the_title_page_names_the_book_its_version_and_its_downloads(pages):
    """The citation (CITATION.cff, through the pages' <meta> tags) and the downloads on page 1; no rubric."""
    rubrics = [source_title(docname) for docname in instructors_only()]     # (puts book/_ext on the path)
    import companion

    citation = yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))
    first = typographic(pages[0])
    assert citation["authors"][0]["name"] in first
    version_line = TITLE_PAGE["en"]["version"].format(version=companion.version(),
                                                      date=citation["date-released"].isoformat())
    assert version_line in first
    assert companion.wheel_name() in first and companion.archive_name() in first
    assert rubrics and [t for t in rubrics if typographic(t) in typographic(" ".join(pages))] == []
    left = [source_title(docname) for docname in SITE_ONLY]                  # the library reference
    assert left and [t for t in left if typographic(t) in typographic(" ".join(pages))] == []
