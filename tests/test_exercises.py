"""Exercise notebooks: solutions run and pass their checks; student versions stop only at placeholders.

Each exercise notebook is written once, with its solutions. ``exercises/make_student.py``
makes the student version. These tests show:

- every solution notebook executes, and every one of its checks says "right";
- every student notebook executes with only "not yet answered" errors, one per placeholder;
- a wrong answer fed to each check is reported as wrong (a check that cannot fail is a defect).
"""

import importlib
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXERCISES = ROOT / "exercises"
NOTEBOOKS = sorted(EXERCISES.glob("[0-9][0-9]-*.md"))
sys.path.insert(0, str(EXERCISES))
make_student = importlib.import_module("make_student")


def checks_of(path):
    return importlib.import_module(f"checking.ch{path.name[:2]}").CHECKS


def execute(notebook, allow_errors=False):
    import nbclient

    client = nbclient.NotebookClient(notebook, timeout=300, kernel_name="python3", allow_errors=allow_errors,
                                     resources={"metadata": {"path": str(EXERCISES)}})
    client.execute()
    return notebook


def text_of(cell):
    return "".join(o.get("text", "") for o in cell.get("outputs", []) if o.get("output_type") == "stream")


def test_one_exercise_notebook_per_chapter():
    chapters = sorted(p.name for p in (ROOT / "chapters").glob("*.md"))
    assert [p.name for p in NOTEBOOKS] == chapters


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_solution_notebook_runs_and_every_check_says_right(path):
    import jupytext

    notebook = execute(jupytext.read(path))
    output = "\n".join(text_of(c) for c in notebook.cells if c.cell_type == "code")
    labels = list(checks_of(path))
    assert len(labels) >= 4
    for label in labels:
        assert f"Exercise {label}: right." in output, f"exercise {label} was not checked, or is wrong"
    assert "not right yet" not in output


@pytest.fixture(scope="module")
def student_notebooks(tmp_path_factory):
    return make_student.write_student_versions(tmp_path_factory.mktemp("student"))


@pytest.mark.parametrize("index", range(len(NOTEBOOKS)), ids=[p.stem for p in NOTEBOOKS])
def test_student_notebook_stops_only_at_its_placeholders(student_notebooks, index):
    import nbformat

    path = student_notebooks[index]
    notebook = nbformat.read(path, as_version=4)
    source = "\n".join(c.source for c in notebook.cells)
    assert "BEGIN SOLUTION" not in source and "{solution" not in source and "STUDENT:" not in source
    placeholders = sum(c.source.count("= ...") for c in notebook.cells if c.cell_type == "code")
    assert placeholders == len(checks_of(path))
    import nbclient

    nbclient.NotebookClient(notebook, timeout=300, kernel_name="python3", allow_errors=True,
                            resources={"metadata": {"path": str(path.parent)}}).execute()
    errors = [o for c in notebook.cells for o in c.get("outputs", []) if o.get("output_type") == "error"]
    assert [e["ename"] for e in errors] == ["NotAnswered"] * placeholders
    assert all("is not yet answered" in e["evalue"] for e in errors)


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_every_check_reports_a_wrong_answer_as_wrong(path, capsys):
    from checking import NotAnswered

    for label, check in checks_of(path).items():
        assert check(check.wrong_example(check.expected_value())) is False, f"{label} accepts a wrong answer"
        assert f"Exercise {label}: not right yet. Hint:" in capsys.readouterr().out
        assert check(check.expected_value()) is True
        with pytest.raises(NotAnswered, match=f"Exercise {label} is not yet answered"):
            check(...)


def exercise_numbers(path):
    """The numbers in the titles of a page's ``{exercise}`` blocks, in order ("6.1", "6.2", ...)."""
    import re

    titles = re.findall(r"^`{3,}\{exercise\} (.*)$", path.read_text(), flags=re.M)
    return [re.match(r"(\d+\.\d+): ", title).group(1) if re.match(r"\d+\.\d+: ", title) else title
            for title in titles]


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_one_numbering_from_the_chapter_to_its_exercise_page_and_its_checks(path):
    """Chapter N's exercises are N.1 .. N.k, its page's N.k+1 .. N.k+m, and the checks are the page's."""
    import re

    n = int(path.name[:2])
    chapter = ROOT / "chapters" / path.name
    in_chapter, on_page = exercise_numbers(chapter), exercise_numbers(path)
    assert in_chapter + on_page == [f"{n}.{k}" for k in range(1, len(in_chapter) + len(on_page) + 1)]
    assert list(checks_of(path)) == on_page
    assert re.findall(r'check\("([\d.]+)"', path.read_text()) == on_page
    # every {exercise} is unnumbered by sphinx-exercise, so that its title's number is the only one
    assert chapter.read_text().count(":nonumber:") == len(in_chapter)
    # the chapter ends with a link to its exercise page, which links back at its top
    tail = chapter.read_text().rstrip().splitlines()[-2:]
    assert f"{{doc}}`../exercises/{path.stem}`" in " ".join(tail)
    assert f"{on_page[0]} to {on_page[-1]}" in " ".join(tail)
    head = path.read_text().split("```{code-cell}")[0]
    assert f"{{doc}}`../chapters/{path.stem}`" in head and f"{in_chapter[0]} to {in_chapter[-1]}" in head
