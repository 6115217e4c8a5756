"""The course edition (``make course``, ``book/_ext/companion.py``): the site without any solution.

An instructor publishes it to a class. It must hold no solution anywhere a student can reach: no
sentence of a solution's prose and no line of a solution's code on any page (read from the pages'
sources, as the PDF's test reads them), no check's verdict ("Exercise 3.5: right."), no page's MyST
source, no rubric, and none of these in its notebook downloads or in its archive either. Every
exercise statement stays, with its time and difficulty.

The same detector is run on the self-study edition (``make book``), which must still show what the
course edition hides: otherwise the detector would find nothing anywhere, and the test would prove
nothing.

The course edition is built once for the session after the book (the ``built_course`` fixture of
conftest.py); ``CLOSEDLOOP_SITE_BUILT=1`` reads the ``_build/course/html`` already there.
"""

import json
import re
import sys
import zipfile
from functools import lru_cache
from pathlib import Path

import pytest

from .test_pdf import code_lines, exercise_parts, plain_sentences, typographic

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "book" / "_ext"))
from companion import INSTRUCTORS_ONLY, archive_name  # noqa: E402

#: The pages that hold exercises, and so solutions: the chapters and the exercise pages.
PAGES = [f"chapters/{p.stem}" for p in sorted((ROOT / "chapters").glob("[0-9][0-9]-*.md"))] + \
        [f"exercises/{p.stem}" for p in sorted((ROOT / "exercises").glob("[0-9][0-9]-*.md"))]
#: A check's verdict, as its output prints it (exercises/checking).
VERDICT = re.compile(r"Exercise \d+\.\d+: (right\.|not right yet)")


@lru_cache(maxsize=None)
def solution_parts(page):
    """(sentences, code lines) of the page's solutions that the page shows nowhere else."""
    text = (ROOT / f"{page}.md").read_text(encoding="utf-8")
    asked, solved = exercise_parts(text)
    outside = text
    for part in solved:
        outside = outside.replace("\n".join(part), "")
    outside = typographic(outside)
    sentences = [s for part in solved for s in plain_sentences(part) if typographic(s) not in outside]
    # a gated solution's cell ends in its check call, which the student version keeps: not a solution
    code = [line for part in solved for line in code_lines(part)
            if typographic(line) not in outside and not line.startswith("check(")]
    return sentences, code


@lru_cache(maxsize=None)
def page_text(path):
    """The text of a page's article, whitespace single and quotes straight (code included)."""
    import html

    text = path.read_text(encoding="utf-8")
    article = text[text.find("<article"):text.rfind("</article>")]
    return typographic(html.unescape(re.sub(r"<[^>]+>", " ", article)))


def squeezed(text):
    """``text`` without any whitespace: a highlighted code line is split into tokens by the page."""
    return re.sub(r"\s+", "", text)


def held(page, text, prose=True):
    """The solution sentences (if ``prose``) and code lines of ``page`` that ``text`` holds."""
    sentences, code = solution_parts(page)
    flat = squeezed(text)
    return [s for s in sentences if prose and typographic(s) in text] + [c for c in code if squeezed(c) in flat]


def test_the_detector_sees_the_solutions_of_the_self_study_edition(built_site):
    shown = {page: held(page, page_text(built_site / f"{page}.html")) for page in PAGES}
    assert [page for page, found in shown.items() if not found] == [], \
        "the self-study edition shows no solution on these pages: the detector finds nothing"
    assert sum(len(page_text(built_site / f"{page}.html").split("Exercise ")) for page in PAGES) > 100


@pytest.mark.parametrize("edition", ["", "vi/"], ids=["en", "vi"])
@pytest.mark.parametrize("page", PAGES)
def test_a_page_of_the_course_edition_shows_no_solution(built_course, built_site, edition, page):
    html = (built_course / edition / f"{page}.html").read_text(encoding="utf-8")
    text = page_text(built_course / edition / f"{page}.html")
    # the English edition: no sentence, no code line; the Vietnamese one translates the prose, so its code
    assert held(page, text, prose=not edition) == []
    assert 'class="solution' not in html and "Solution to" not in text and "Lời giải cho" not in text
    assert not VERDICT.search(text), f"{page}: a check's verdict"
    # every exercise stays, each with its time and difficulty
    self_study = (built_site / edition / f"{page}.html").read_text(encoding="utf-8")
    exercises = self_study.count('class="exercise admonition')
    assert exercises >= 3 and html.count('class="exercise admonition') == exercises
    assert html.count('class="exercise-effort"') == exercises


@pytest.mark.parametrize("edition", ["", "vi/"], ids=["en", "vi"])
def test_the_course_edition_offers_no_source_and_no_rubric(built_course, edition):
    site = built_course / edition
    assert sorted(path.name for path in (site / "_sources").rglob("*.md")) == []
    for page in INSTRUCTORS_ONLY:
        assert not (site / f"{page}.html").exists()
        name = Path(page).name
        linked = [path.relative_to(site).as_posix() for path in site.rglob("*.html")
                  if re.search(rf'href="[^"]*{re.escape(name)}\.html', path.read_text(encoding="utf-8"))]
        assert linked == [], f"{page} is linked from {linked}"


@pytest.mark.parametrize("page", PAGES)
def test_a_download_of_the_course_edition_holds_no_solution(built_course, page):
    notebook = json.loads((built_course / "_sources" / f"{page}.ipynb").read_text(encoding="utf-8"))
    text = typographic(" ".join("".join(cell["source"]) for cell in notebook["cells"]))
    outputs = json.dumps([cell.get("outputs", []) for cell in notebook["cells"]])
    assert held(page, text) == []
    assert not VERDICT.search(outputs) and "#### Solution" not in text


def test_the_archive_of_the_course_edition_holds_no_solution(built_course, built_site):
    with zipfile.ZipFile(built_course / "_downloads" / archive_name()) as archive:
        notebooks = {name: json.loads(archive.read(name)) for name in archive.namelist() if name.endswith(".ipynb")}
        wheel = [name for name in archive.namelist() if name.endswith(".whl")]
        assert archive.read(wheel[0]) == (built_site / "_downloads" / Path(wheel[0]).name).read_bytes()
    assert len(notebooks) == len(list((built_site / "_sources").rglob("*.ipynb")))
    for name, notebook in notebooks.items():
        page = name.split("/", 1)[1].removesuffix(".ipynb")
        if page in PAGES:
            text = typographic(" ".join("".join(cell["source"]) for cell in notebook["cells"]))
            assert held(page, text) == [], name
            assert not VERDICT.search(json.dumps([cell.get("outputs", []) for cell in notebook["cells"]])), name
