"""Generate the student version of every exercise notebook.

    python exercises/make_student.py [OUTPUT_DIR]        (default: _build/student)

Each exercise notebook is written once, with its solutions (MyST Markdown). The
student version is the same notebook with:

- every ``{solution}`` block removed, and each ``{exercise}`` shown as a plain heading, which ends
  with the exercise's expected time and difficulty (``exercises/effort.yml``);
- every gated solution (``{solution-start}`` ... ``{solution-end}``) removed, except
  its code cells that hold a ``# BEGIN SOLUTION`` / ``# END SOLUTION`` block: that
  block is replaced by the lines written after ``# STUDENT:`` inside it, typically
  ``answer = ...``, so that the cell's ``check(...)`` call says "not yet answered";
- the same replacement in code cells outside solutions.

The result is saved as .ipynb for handing out, with the ``checking`` package
beside it, its markdown made plain (``book/_ext/plain_notebook.py``: no MyST directive or
role left, which Jupyter would show as raw text). The book's download of an exercise page
is this same student version (``book/_ext/ipynb_download.py``). Student notebooks are
build outputs and are never committed.
"""

from __future__ import annotations

import functools
import re
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
FENCE = re.compile(r"^(?P<fence>`{3,}|:{3,})\s*\{(?P<name>[\w-]+)\}")
NOTICE = ("> **Student version.** Replace each `...` with your answer and run the cell: its check says "
          "whether the answer is right, with a hint if it is not.\n")


def student_code(lines):
    """A code cell's lines with each solution block replaced by its ``# STUDENT:`` lines."""
    out, inside, placeholder = [], False, []
    for line in lines:
        stripped = line.strip()
        if stripped.startswith("# BEGIN SOLUTION"):
            inside, placeholder = True, []
            indent = line[: len(line) - len(line.lstrip())]
        elif stripped.startswith("# END SOLUTION"):
            if not placeholder:
                raise ValueError("a solution block has no '# STUDENT:' line to leave in its place")
            out += placeholder
            inside = False
        elif inside:
            if stripped.startswith("# STUDENT:"):
                placeholder.append(indent + stripped[len("# STUDENT:"):].strip() + "\n")
        else:
            out.append(line)
    if inside:
        raise ValueError("a '# BEGIN SOLUTION' has no '# END SOLUTION'")
    return out


def _closing_fence(lines, i, fence):
    """The index of the line that closes the directive opened at line ``i`` with ``fence``."""
    j = i + 1
    while j < len(lines) and lines[j].strip() != fence:
        j += 1
    return j


def _past_solution(lines, i, match, gated):
    """The line after the solution directive opened at line ``i`` (``match``), and whether what follows
    lies between a ``{solution-start}`` and its ``{solution-end}``."""
    gates = {"solution": gated, "solution-start": True, "solution-end": False}
    return _closing_fence(lines, i, match.group("fence")) + 1, gates[match.group("name")]


def student_markdown(text: str) -> str:
    """The MyST source of the student version (see the module docstring)."""
    lines = text.splitlines(keepends=True)
    out, i, gated = [], 0, False
    while i < len(lines):
        match = FENCE.match(lines[i])
        name = match.group("name") if match else None
        if name in ("solution", "solution-start", "solution-end"):
            i, gated = _past_solution(lines, i, match, gated)
            continue
        if name == "exercise" and not gated:         # a plain heading: Jupyter cannot render directives
            title = lines[i][match.end():].strip()
            j, body = i + 1, []
            while j < len(lines) and lines[j].strip() != match.group("fence"):
                if lines[j].startswith(":label:"):
                    number = lines[j].split(":label:")[1].strip().split("-", 1)[-1].replace("-", ".")
                else:
                    body.append(lines[j])
                j += 1
            heading = title if title.startswith(f"{number}:") else f"{number}: {title}"
            heading += f" · {_plain_notebook().exercise_effort(number)}"     # its time and difficulty
            out += [f"### Exercise {heading}\n"] + (body[1:] if body and body[0].strip() == ":nonumber:" else body)
            i = j + 1
            continue
        if name == "code-cell":
            j = _closing_fence(lines, i, match.group("fence"))
            body = lines[i + 1: j]
            has_solution = any(line.strip().startswith("# BEGIN SOLUTION") for line in body)
            if not gated or has_solution:
                out += [lines[i], *student_code(body), lines[j]]
            i = j + 1
            continue
        if not gated:
            out.append(lines[i])
        i += 1
    text = "".join(out)
    # the notice goes right after the first heading
    return re.sub(r"^(# .+\n)", lambda m: m.group(1) + "\n" + NOTICE, text, count=1, flags=re.M)


def markdown_without_solutions(text: str, gated: bool = False) -> tuple[str, bool]:
    """``text`` (one markdown cell's MyST source) without its ``{solution}`` blocks and without what lies
    between a ``{solution-start}`` and its ``{solution-end}``; ``gated`` says whether the cell starts inside
    such a pair. Returns the text and whether the cell ends inside one."""
    lines = text.splitlines(keepends=True)
    out, i = [], 0
    while i < len(lines):
        match = FENCE.match(lines[i])
        name = match.group("name") if match else None
        if name in ("solution", "solution-start", "solution-end"):
            i, gated = _past_solution(lines, i, match, gated)
            continue
        if not gated:
            out.append(lines[i])
        i += 1
    return "".join(out), gated


def without_solutions(notebook):
    """``notebook`` (a chapter's executed notebook, changed in place and returned) without any solution:
    no ``{solution}`` block, and no cell, markdown or code (with its output), of a gated solution. The
    course edition's download of a chapter (``book/_ext/companion.py``)."""
    cells, gated = [], False
    for cell in notebook.cells:
        if cell.cell_type == "markdown":
            cell.source, gated = markdown_without_solutions(cell.source, gated)
            if cell.source.strip():
                cells.append(cell)
        elif not gated:
            cells.append(cell)
    if gated:
        raise ValueError("a '{solution-start}' has no '{solution-end}'")
    notebook.cells = cells
    return notebook


def exercise_notebooks():
    return sorted(HERE.glob("[0-9][0-9]-*.md"))


@functools.cache
def _plain_notebook():
    """The book's converter of MyST Markdown to plain Markdown (book/_ext/plain_notebook.py)."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("plain_notebook", HERE.parent / "book" / "_ext" / "plain_notebook.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def write_student_versions(output: Path) -> list[Path]:
    """Write one student .ipynb per exercise notebook into ``output``; return their paths."""
    import shutil

    import jupytext

    output.mkdir(parents=True, exist_ok=True)
    # the notebooks' checks travel with them (they compute the answers with closedloop)
    shutil.copytree(HERE / "checking", output / "checking", dirs_exist_ok=True,
                    ignore=shutil.ignore_patterns("__pycache__"))
    written = []
    for source in exercise_notebooks():
        target = output / f"{source.stem}.ipynb"
        jupytext.write(student_notebook(source), target, fmt="ipynb")
        written.append(target)
    return written


def student_notebook(source: Path):
    """The student version of the exercise notebook ``source`` (a path in exercises/), as a notebook object."""
    import jupytext

    plain = _plain_notebook()
    notebook = jupytext.reads(student_markdown(source.read_text()), fmt="md:myst")
    plain.convert_notebook(notebook, plain.Resolver(f"exercises/{source.stem}", HERE.parent))
    return notebook


if __name__ == "__main__":
    destination = Path(sys.argv[1]) if len(sys.argv) > 1 else HERE.parent / "_build" / "student"
    for path in write_student_versions(destination):
        print(path)
