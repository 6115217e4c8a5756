"""Exercise notebooks: solutions run and pass their checks; student versions stop only at placeholders.

Each exercise notebook is written once, with its solutions. ``exercises/make_student.py``
makes the student version. These tests show:

- every solution notebook executes, and every one of its checks says "right" (read from the book's
  build, which executes each page once: the ``built_site`` fixture of conftest.py);
- every student version keeps one ``...`` per check and no solution (tests/test_downloads.py runs
  each, as a reader downloads it, and sees it stop only at its placeholders);
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


def executed_by_the_build(path, site):
    """The exercise page ``path`` as the book's build executed it (its outputs, from the execution cache).

    The build runs every exercise page once, with its solutions; this reads that run instead of
    running the page again.
    """
    import jupytext
    from jupyter_cache import get_cache

    try:
        _, notebook = get_cache(site.parent / ".jupyter_cache").merge_match_into_notebook(jupytext.read(path))
    except KeyError:
        pytest.fail(f"{path.name}: the build's execution cache holds no run of this page's current source")
    return notebook


def text_of(cell):
    return "".join(o.get("text", "") for o in cell.get("outputs", []) if o.get("output_type") == "stream")


def test_one_exercise_notebook_per_chapter():
    chapters = sorted(p.name for p in (ROOT / "chapters").glob("*.md"))
    assert [p.name for p in NOTEBOOKS] == chapters


@pytest.mark.parametrize("path", NOTEBOOKS, ids=lambda p: p.stem)
def test_solution_notebook_runs_and_every_check_says_right(path, built_site):
    notebook = executed_by_the_build(path, built_site)
    code = [c for c in notebook.cells if c.cell_type == "code"]
    assert [c.get("execution_count") for c in code] == list(range(1, len(code) + 1)), \
        f"{path.name}: not run top to bottom in one kernel"
    errors = [o for c in code for o in c.get("outputs", []) if o.get("output_type") == "error"]
    assert errors == [], f"{path.name}: {[e['ename'] + ': ' + e['evalue'] for e in errors]}"
    output = "\n".join(text_of(c) for c in code)
    labels = list(checks_of(path))
    assert len(labels) >= 4
    for label in labels:
        assert f"Exercise {label}: right." in output, f"exercise {label} was not checked, or is wrong"
    assert "not right yet" not in output


def test_the_student_versions_keep_every_check_and_no_solution(tmp_path):
    """``make student`` (make_student.py): one notebook per page, one ``...`` per check, no solution.

    Each student version is run, as a reader downloads it, by tests/test_downloads.py.
    """
    import nbformat

    written = make_student.write_student_versions(tmp_path)
    assert [p.stem for p in written] == [p.stem for p in NOTEBOOKS]
    assert (tmp_path / "checking" / "__init__.py").exists()
    for path in written:
        cells = nbformat.read(path, as_version=4).cells
        source = "\n".join(c.source for c in cells)
        assert "BEGIN SOLUTION" not in source and "{solution" not in source and "STUDENT:" not in source, path.name
        placeholders = sum(c.source.count("= ...") for c in cells if c.cell_type == "code")
        assert placeholders == len(checks_of(path)), path.name


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


def test_every_exercise_states_its_time_and_difficulty():
    """exercises/effort.yml lists every exercise of the book, chapters and exercise pages, and no other."""
    import yaml

    listed = yaml.safe_load((EXERCISES / "effort.yml").read_text())
    numbers = [n for path in NOTEBOOKS for n in exercise_numbers(ROOT / "chapters" / path.name) + exercise_numbers(path)]
    assert len(numbers) > 100 and sorted(listed) == sorted(numbers)
    for number, (minutes, level) in listed.items():
        assert isinstance(minutes, int) and 5 <= minutes <= 60 and level in ("easy", "medium", "hard"), number
    assert {level for _, level in listed.values()} == {"easy", "medium", "hard"}


def test_the_student_versions_state_each_exercise_s_time_and_difficulty():
    import re

    import yaml

    listed = yaml.safe_load((EXERCISES / "effort.yml").read_text())
    for path in NOTEBOOKS:
        headings = re.findall(r"^### Exercise (\d+\.\d+): .* · (\d+) min · (\w+)$",
                              make_student.student_markdown(path.read_text()), re.M)
        assert [number for number, _, _ in headings] == exercise_numbers(path), path.name
        assert all(listed[n] == [int(m), level] for n, m, level in headings), path.name


@pytest.mark.parametrize("edition", ["", "vi/"], ids=["en", "vi"])
def test_the_site_states_each_exercise_s_time_and_difficulty(built_site, edition):
    """After each exercise's title, "· 10 min · easy" (the Vietnamese edition: "· 10 phút · dễ")."""
    import re

    import yaml

    listed = yaml.safe_load((EXERCISES / "effort.yml").read_text())
    words = {"": ("min", {"easy": "easy", "medium": "medium", "hard": "hard"}),
             "vi/": ("phút", {"easy": "dễ", "medium": "trung bình", "hard": "khó"})}[edition]
    for path in NOTEBOOKS:
        for page in (f"chapters/{path.stem}", f"exercises/{path.stem}"):
            text = (built_site / edition / f"{page}.html").read_text()
            shown = re.findall(r'(\d+\.\d+) \(.*?<span class="exercise-effort"> · (\d+) (\S+) · ([^<]+)</span>', text)
            numbers = exercise_numbers(ROOT / f"{page}.md")
            assert [number for number, *_ in shown] == numbers, page
            for number, minutes, unit, level in shown:
                assert (int(minutes), unit, level) == (listed[number][0], words[0], words[1][listed[number][1]]), \
                    f"{page}: {number}"
