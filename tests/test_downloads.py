"""The notebooks a reader downloads from the built site, read and run as a reader would.

Every notebook page of the site (the thirteen chapters, their exercise pages, the notation page
and the appendix on chapter 8's data) offers its notebook in its download menu
(``_build/html/_sources/<page>.ipynb``, made by ``book/_ext/ipynb_download.py``), and each is
checked. A download fails on:

- MyST markup in a markdown cell: a directive fence (```` ```{note} ````), a role
  (``{doc}`...` ``), a ``:label:`` line, a target ``(label)=``, a MyST comment; Jupyter shows
  all of them as raw text;
- a build marker (``BEGIN SOLUTION``, ``END SOLUTION``, ``STUDENT:``) in any cell;
- in an exercise page's download, a solution: a solution heading, a line of a solution's code
  or a sentence of a solution's prose.

A chapter's download is the notebook the book's build executed (the build runs every chapter once,
and stops on any error): its code cells must be the ones its page shows (the cells tagged
``remove-cell``, which glue computed values into the prose, are left out, and no cell left calls
``glue``), in order, each run once, top to bottom, in one kernel, with no error, and every data file
its code names must be linked from its first cell (the files a reader fetches beside it).

**In a plain Jupyter.** Every download is then run as a reader runs it: in a fresh virtual
environment that holds only the site's own wheel with its ``plot`` extra, ipykernel and nbclient (no
Jupyter Book, no MyST-NB, nothing of the repository), made once for the session from the built site
(pip installs the versions ``requirements/lock.txt`` pins, from the files pip already has), each
download copied alone into a fresh folder with only the files its first cell links to (fetched as a
reader would), and run top to bottom by that environment's nbclient in a kernel of that environment
(``tests/plain_jupyter.py``), two at a time. A chapter and the other pages must run without an error;
an exercise page may stop only at its "not yet answered" placeholders, one per ``...``.

The site is built once for the session (the ``built_site`` fixture of conftest.py, the README's
``make book``); set ``CLOSEDLOOP_SITE_BUILT=1`` to test the ``_build/html`` already there instead.
"""

from __future__ import annotations

import os
import re
import shutil
import zipfile
from pathlib import Path

import pytest

from ._toc import toc_pages

ROOT = Path(__file__).resolve().parents[1]
HTML = ROOT / "_build" / "html"
#: Every page with a download: each page of the table of contents that is a notebook (a jupytext header).
DOWNLOADS = [page for page in toc_pages() if (ROOT / f"{page}.md").read_text().startswith("---\njupytext:")]
PAGES = [p for p in DOWNLOADS if p.startswith(("chapters/", "exercises/"))]
EXERCISE_PAGES = [p for p in PAGES if p.startswith("exercises/")]
#: File names a chapter's code may read beside its notebook (data), which its first cell must link.
DATA_FILE = re.compile(r"""["']([\w.-]+\.(?:json|csv|npz|npy|txt|dat))["']""")
MARKERS = ("BEGIN SOLUTION", "END SOLUTION", "STUDENT:")


# --- what plain Jupyter would show as raw MyST -----------------------------------------------
FENCE = re.compile(r"^[ \t>]*(`{3,}|~{3,}|:{3,})[ \t]*\{[^}\n]*\}", re.M)
LABEL = re.compile(r"^[ \t>]*:(label|name|class|nonumber|numbered|alt|align|header-rows):", re.M)
TARGET = re.compile(r"^[ \t>]*\([\w:.-]+\)=[ \t]*$", re.M)
COMMENT = re.compile(r"^%", re.M)
ROLE = re.compile(r"\{[A-Za-z][\w:+-]*\}`")
CODE = re.compile(r"^[ \t]*(`{3,}|~{3,})[^\n]*\n.*?^[ \t]*\1[ \t]*$|(`+)(?!`).+?(?<!`)\2(?!`)", re.M | re.S)


def myst_markup(text: str) -> list[str]:
    """The pieces of MyST syntax in ``text`` that CommonMark does not have (empty if none)."""
    found = [m.group(0).strip() for m in FENCE.finditer(text)]
    prose = CODE.sub(lambda m: "" if m.group(1) else "`code`", text)    # code shows as written: not markup
    found += [m.group(0).strip() for pattern in (LABEL, TARGET, COMMENT, ROLE) for m in pattern.finditer(prose)]
    return found


@pytest.mark.parametrize("text", [
    "```{note}\nHello\n```",
    "::::{admonition} Hi\n:class: tip\nbody\n::::",
    "See {doc}`../chapters/06-four-cases`.",
    "As {cite:p}`khang2018` shows",
    "the value {glue:text}`speed:.2f` rad/s",
    "(sec-intro)=\n# Intro",
    "% a comment\ntext",
    "some text\n:label: ex-1\n",
    "> ```{warning}\n> x\n> ```",
    "a {prf:ref}`thm` b",
])
def test_the_myst_detector_finds_markup(text):
    assert myst_markup(text)


@pytest.mark.parametrize("text", [
    "# Title\n\nText with $x^2$ and $$a = b$$ and a [link](x.ipynb) and **bold**.",
    "```python\nx = {1: 2}\n```",
    "A code span ``{doc}`x` `` shows the syntax, as does `` {ref}`y` ``.",
    "> **Note**\n>\n> body\n\n### Exercise 6.3: title",
    "50 % of it",
    "![alt](attachment:1-figure.png)",
])
def test_the_myst_detector_passes_plain_markdown(text):
    assert myst_markup(text) == []


# --- the solutions that an exercise page's download must not hold ----------------------------
def solutions(page):
    """(code lines, prose sentences) found only inside the solutions of an exercise page's source."""
    import jupytext

    notebook = jupytext.read(ROOT / f"{page}.md")
    inside, code, prose, outside = False, set(), set(), set()
    for cell in notebook.cells:
        if cell.cell_type == "markdown":
            for block in re.split(r"^(?=[`:]{3,})", cell.source, flags=re.M):
                opens = re.match(r"^[`:]{3,}\{(solution|solution-start|solution-end)\}", block)
                if opens:
                    inside = opens.group(1) != "solution-end"
                    body = block.split("\n", 1)[-1] if opens.group(1) != "solution-end" else ""
                    prose.update(s.strip() for s in re.split(r"(?<=[.:])\s+", body) if len(s.strip()) > 40
                                 and not s.strip().startswith(":") and "```" not in s)
                    if opens.group(1) == "solution":
                        inside = False
                elif inside:
                    prose.update(s.strip() for s in re.split(r"(?<=[.:])\s+", block) if len(s.strip()) > 40)
        else:
            block, gated = False, inside and "# BEGIN SOLUTION" not in cell.source   # a gated cell goes whole
            for line in cell.source.splitlines():
                stripped = line.strip()
                if stripped.startswith("# BEGIN SOLUTION"):
                    block = True
                elif stripped.startswith("# END SOLUTION"):
                    block = False
                elif block or gated:
                    if len(stripped) > 15 and not stripped.startswith("# STUDENT:"):
                        code.add(stripped)
                else:
                    outside.add(stripped)
    return code - outside, prose


# --- running a download as a reader would, in a plain Jupyter ---------------------------------
def site_wheel():
    """The wheel the site offers (``_downloads/closedloop-<version>-py3-none-any.whl``)."""
    found = sorted((HTML / "_downloads").glob("closedloop-*-py3-none-any.whl"))
    assert len(found) == 1, f"the site offers {len(found)} wheels: {found}"
    return found[0]


def plain_environment_variables(home):
    """What a reader's shell would have: no PYTHONPATH, no Jupyter settings, no virtual environment
    of ours, no PYTHONDONTWRITEBYTECODE (the first kernel to import a module compiles it for the
    others, as on a reader's machine); a home of its own; the session's code cache (conftest.py)."""
    keep = ("PATH", "LANG", "LC_ALL", "TMPDIR", "CLOSEDLOOP_CACHE_DIR")
    env = {name: os.environ[name] for name in keep if name in os.environ}
    env.update(HOME=str(home), MPLBACKEND="agg")
    return env


@pytest.fixture(scope="module")
def plain_python(built, tmp_path_factory):
    """The Python of a fresh virtual environment holding the site's wheel with its ``plot`` extra,
    ipykernel and nbclient, and nothing else (no pip either: the project's pip installs into it).

    pip takes the versions requirements/lock.txt pins, from the files it already has (the
    project's environment was made from the same lock). It compiles nothing: each module is
    compiled when a kernel first imports it (two thirds of what pip would compile is never imported).
    """
    import subprocess
    import sys
    import venv

    folder = tmp_path_factory.mktemp("plain-jupyter") / "env"
    venv.EnvBuilder(with_pip=False).create(folder)
    python = folder / "bin" / "python"
    subprocess.run([sys.executable, "-m", "pip", "--python", str(python), "install", "--quiet",
                    "--disable-pip-version-check", "--no-compile", "-c", str(ROOT / "requirements" / "lock.txt"),
                    f"{site_wheel()}[plot]", "ipykernel", "nbclient"], check=True, capture_output=True)
    return python


def fetch(page, folder):
    """Copy ``page``'s download into ``folder``, with what its first cell links to (a .zip unpacked there)."""
    import nbformat

    source = HTML / "_sources" / f"{page}.ipynb"
    links = re.findall(r"\]\(([^)]+)\)", nbformat.read(source, as_version=4).cells[0].source)
    for link in links:
        fetched = source.parent / link
        if link.endswith(".zip"):
            with zipfile.ZipFile(fetched) as archive:
                archive.extractall(folder)
        elif fetched.is_file():
            (folder / link).parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(fetched, folder / link)
    shutil.copyfile(source, folder / source.name)
    return source.name


def run_plain(python, home, pages):
    """Each of ``pages``' downloads run in a fresh folder of its own by the plain environment, one after
    the other in one runner process (tests/plain_jupyter.py), each in a fresh kernel.

    Returns {page: (the executed notebook, the runner's report: the kernel's prefix, and why it stopped early)}.
    """
    import json
    import subprocess
    import tempfile

    import nbformat

    jobs = []
    for page in pages:
        folder = Path(tempfile.mkdtemp(prefix="reader-"))
        jobs.append((page, folder, fetch(page, folder), folder.parent / f"{folder.name}.out.ipynb"))
    try:
        done = subprocess.run([str(python), str(ROOT / "tests" / "plain_jupyter.py"),
                               *[str(part) for _, folder, name, output in jobs for part in (folder, name, output)]],
                              cwd=home, env=plain_environment_variables(home), capture_output=True, text=True,
                              timeout=900 * len(jobs))
        assert done.returncode == 0, f"{pages}: the runner failed:\n{done.stderr[-3000:]}"
        reports = [json.loads(line) for line in done.stdout.strip().splitlines() if line.startswith("{")]
        assert len(reports) == len(jobs), done.stdout[-2000:]
        return {page: (nbformat.read(output, as_version=4), report)
                for (page, _, _, output), report in zip(jobs, reports)}
    finally:
        for _, folder, _, output in jobs:
            shutil.rmtree(folder, ignore_errors=True)
            output.unlink(missing_ok=True)


@pytest.fixture(scope="module")
def built(built_site):
    return built_site


@pytest.fixture(scope="module")
def executed(plain_python, tmp_path_factory):
    """Every download, run once in a plain Jupyter, each in its own fresh folder (two at a time)."""
    from concurrent.futures import ThreadPoolExecutor

    home = tmp_path_factory.mktemp("reader-home")
    # one runner per core, each given every other page, the chapters first (they take longest, so that
    # the runners end together rather than one waiting for the other)
    workers = max(1, min(2, os.cpu_count() or 1))
    order = sorted(DOWNLOADS, key=lambda page: not page.startswith("chapters/"))
    executed = {}
    with ThreadPoolExecutor(max_workers=workers) as pool:
        for found in pool.map(lambda k: run_plain(plain_python, home, order[k::workers]), range(workers)):
            executed.update(found)
    return executed


def downloaded(page):
    import nbformat

    path = HTML / "_sources" / f"{page}.ipynb"
    assert path.exists(), f"{page}: no notebook in the download"
    assert f"_sources/{page}.ipynb" in (HTML / f"{page}.html").read_text(), f"{page}: not in the download menu"
    return nbformat.read(path, as_version=4)


def test_every_notebook_page_offers_its_download_and_nothing_else_is_offered(built):
    offered = sorted(path.relative_to(HTML / "_sources").with_suffix("").as_posix()
                     for path in (HTML / "_sources").rglob("*.ipynb"))
    assert offered == sorted(DOWNLOADS)
    # the thirteen chapters, their thirteen exercise pages, the notation page and the appendix
    assert len(DOWNLOADS) == 28 and {"book/notation", "book/appendix-provenance"} <= set(DOWNLOADS)


@pytest.mark.parametrize("page", DOWNLOADS)
def test_a_download_has_no_myst_and_no_marker(built, page):
    notebook = downloaded(page)
    for index, cell in enumerate(notebook.cells):
        if cell.cell_type == "markdown":
            assert myst_markup(cell.source) == [], f"{page}, cell {index}: MyST markup left"
        assert not [m for m in MARKERS if m in cell.source], f"{page}, cell {index}: a build marker"


@pytest.mark.parametrize("page", [p for p in PAGES if p.startswith("exercises/")])
def test_an_exercise_download_is_the_student_version(built, page):
    notebook = downloaded(page)
    assert not (HTML / "_sources" / f"{page}.md").exists(), f"{page}: its source, with the solutions, is offered"
    code_lines, sentences = solutions(page)
    assert code_lines and sentences, f"{page}: no solution found in the source (the test would prove nothing)"
    code = "\n".join(c.source for c in notebook.cells if c.cell_type == "code")
    prose = " ".join(" ".join(c.source.split()) for c in notebook.cells if c.cell_type == "markdown")
    assert not [line for line in code_lines if line in code], f"{page}: solution code in the download"
    assert not [s for s in sentences if " ".join(s.split()) in prose], f"{page}: solution prose in the download"
    assert not re.search(r"^#+ Solution", prose, flags=re.M) and "Solution" not in prose
    checks = re.findall(r'check\("([\d.]+)"', code)
    assert checks and code.count("= ...") == len(checks), f"{page}: one placeholder per check"


def test_the_book_has_its_thirteen_chapters():
    assert [p[len("chapters/"):][:2] for p in PAGES if p.startswith("chapters/")] == [f"{k:02d}" for k in
                                                                                      range(1, 14)]


@pytest.mark.parametrize("page", [p for p in PAGES if p.startswith("chapters/")])
def test_a_chapter_download_is_its_source_as_the_build_ran_it(built, page):
    import jupytext

    notebook = downloaded(page)
    code = [c for c in notebook.cells if c.cell_type == "code"]
    cells = [c for c in jupytext.read(ROOT / f"{page}.md").cells if c.cell_type == "code"]
    shown = [c.source for c in cells if "remove-cell" not in c.metadata.get("tags", [])]
    assert code, f"{page} has no code cell: every chapter computes what it shows"
    assert [c.source for c in code] == shown, f"{page}: the download's code is not the code its page shows"
    assert not [c.source for c in code if "glue" in c.source or "myst_nb" in c.source], \
        f"{page}: the download glues values into the prose: the build's business, not the reader's"
    counts = [c.get("execution_count") for c in code]
    assert all(counts) and counts == sorted(set(counts)) and counts[-1] <= len(cells), \
        f"{page}: its cells were not run once each, top to bottom, in one kernel"
    errors = [o for c in code for o in c.get("outputs", []) if o.get("output_type") == "error"]
    assert errors == [], f"{page}: {[e['ename'] + ': ' + e['evalue'] for e in errors]}"
    assert any(c.get("outputs") for c in code), f"{page}: the download holds no output"
    links = {Path(link).name for link in re.findall(r"\]\(([^)]+)\)", notebook.cells[0].source)}
    named = {name for c in code for name in DATA_FILE.findall(c.source)}
    assert named <= links, f"{page}: its code reads {sorted(named - links)}, which its first cell does not link"


def test_the_data_file_detector_finds_what_chapter_8_reads():
    found = DATA_FILE.findall((ROOT / "chapters" / "08-error-vs-runtime.md").read_text())
    assert found and set(found) == {"benchmark.json"}


#: The archive's notebooks that read files beside them, one of each kind: a chapter's data (found by walking
#: up to book/data), the appendix's (data/ beside it) and an exercise page's checks (exercises/checking).
FROM_THE_ARCHIVE = ["chapters/08-error-vs-runtime", "book/appendix-provenance", "exercises/01-closed-loop-systems"]


def test_the_archive_runs_as_unzipped(built, plain_python, tmp_path):
    """The companion's archive, unzipped, runs its notebooks where they lie (the page "Run it yourself")."""
    import json
    import subprocess

    import nbformat

    archive = next((HTML / "_downloads").glob("closedloop-companion-*.zip"))
    with zipfile.ZipFile(archive) as stream:
        stream.extractall(tmp_path)
    top = tmp_path / archive.stem
    for page in FROM_THE_ARCHIVE:
        notebook = top / f"{page}.ipynb"
        output = tmp_path / f"{notebook.stem}.out.ipynb"
        done = subprocess.run([str(plain_python), str(ROOT / "tests" / "plain_jupyter.py"), str(notebook.parent),
                               notebook.name, str(output)], cwd=notebook.parent,
                              env=plain_environment_variables(tmp_path), capture_output=True, text=True, timeout=900)
        assert done.returncode == 0 and "stopped" not in json.loads(done.stdout.splitlines()[-1]), done.stderr[-2000:]
        errors = [o["ename"] for c in nbformat.read(output, as_version=4).cells if c.cell_type == "code"
                  for o in c.get("outputs", []) if o.get("output_type") == "error"]
        assert set(errors) <= ({"NotAnswered"} if page.startswith("exercises/") else set()), f"{page}: {errors}"


def test_the_plain_environment_has_no_book_tool_and_not_the_repository(plain_python):
    import subprocess

    script = ("import importlib.metadata as m, json, closedloop; print(json.dumps([closedloop.__file__, "
              "sorted(d.metadata['Name'].lower() for d in m.distributions())]))")
    done = subprocess.run([str(plain_python), "-c", script], cwd=plain_python.parents[2], check=True,
                          capture_output=True, text=True, env=plain_environment_variables(plain_python.parents[2]))
    import json

    where, installed = json.loads(done.stdout)
    assert Path(where).is_relative_to(plain_python.parents[1]), f"closedloop imported from {where}"
    assert {"closedloop", "matplotlib", "bokeh", "ipykernel", "nbclient"} <= set(installed)
    assert not {"jupyter-book", "myst-nb", "myst-parser", "jupytext", "sphinx", "jupyter-cache", "pytest"} & \
        set(installed)


@pytest.mark.parametrize("page", DOWNLOADS)
def test_a_download_runs_in_a_plain_jupyter(executed, plain_python, page):
    """Run as a reader runs it (see the module's docstring): a chapter with no error; an exercise page
    stops only at its placeholders."""
    notebook, report = executed[page]
    assert "stopped" not in report, f"{page} did not run to its end: {report['stopped']}"
    assert Path(report["prefix"]) == plain_python.parents[1] and \
        Path(report["kernel"][1]).is_relative_to(plain_python.parents[1]), f"{page}: not the plain kernel: {report}"
    code = [c for c in notebook.cells if c.cell_type == "code"]
    assert code and all(c.get("execution_count") for c in code), f"{page}: a code cell was not executed"
    errors = [o for c in code for o in c.get("outputs", []) if o.get("output_type") == "error"]
    placeholders = sum(c.source.count("= ...") for c in code) if page in EXERCISE_PAGES else 0
    assert [e["ename"] for e in errors] == ["NotAnswered"] * placeholders, \
        f"{page}: {[e['ename'] + ': ' + e['evalue'] for e in errors]}"
    assert all("is not yet answered" in e["evalue"] for e in errors)
    assert page not in EXERCISE_PAGES or placeholders >= 4


def test_the_converter_leaves_plain_markdown_and_keeps_math():
    """book/_ext/plain_notebook.py on a sample of every kind of markup the detector knows."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("plain_notebook", ROOT / "book" / "_ext" / "plain_notebook.py")
    plain = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(plain)
    sample = "\n\n".join([
        "(sec-x)=\n## A section", "% a comment",
        "Text {doc}`../chapters/06-four-cases`, {ref}`the outline <preface-course>`, {cite:p}`khang2018`, "
        "$x^2$, {eq}`eq-16`, {glue:text}`speed:.3f` and [(16)](eq-16).",
        ":::{admonition} Take note\n:class: tip\nBody with {term}`drift <constraint drift>`.\n:::",
        "```{exercise} 6.1: The threshold speed\n:label: ex-6-threshold\n:nonumber:\n\nFind it.\n```",
        "```{solution-start} ex-6-threshold\n:class: dropdown\n```",
        "````{note}\nOuter\n```{warning}\nInner\n```\n````",
        "$$\na = b\n$$ (eq-a)",
        "```{prf:theorem} Orthogonality\n:label: thm\nStatement.\n```",
    ])
    assert len(myst_markup(sample)) >= 10
    out = plain.convert_markdown(sample, plain.Resolver("chapters/06-four-cases", ROOT))
    assert myst_markup(out) == [], out
    for kept in ("## A section", "$x^2$", "$$\na = b\n$$", "### Exercise 6.1: The threshold speed", "#### Solution",
                 "> **Take note**", "> > **Warning**", "**Theorem (Orthogonality).**", "(16)", "the outline",
                 "The four cases"):
        assert kept in out, kept
    marked = "# BEGIN SOLUTION\n# STUDENT: x = ...\nx = 1\n# END SOLUTION\ncheck('6.4', x)"
    assert plain.strip_markers(marked) == "x = 1\ncheck('6.4', x)"
