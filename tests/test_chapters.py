"""Every chapter notebook executes from top to bottom without an error.

Chapters are MyST Markdown notebooks; nbmake cannot read them, so jupytext turns
each into a notebook and nbclient runs it in a fresh kernel, from the repository root.
The kernels are separate processes, so the chapters run side by side, one per core
(the longest first); each chapter's test then reads its own outcome.
"""

import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CHAPTERS = sorted((ROOT / "chapters").glob("*.md"))
#: Chapters that take longest, started first so that the cores finish together.
LONGEST_FIRST = ("09", "12", "08", "10", "06")


def _execute(path):
    """The executed notebook of one chapter, or the exception its execution raised."""
    import jupytext
    import nbclient

    notebook = jupytext.read(path)
    client = nbclient.NotebookClient(notebook, timeout=300, kernel_name="python3",
                                     resources={"metadata": {"path": str(ROOT)}})
    try:
        client.execute()                  # raises CellExecutionError, with the cell, on any error
    except Exception as error:            # kept, and raised by the chapter's own test
        return error
    return notebook


@pytest.fixture(scope="module")
def executed():
    order = sorted(CHAPTERS, key=lambda p: (p.name[:2] not in LONGEST_FIRST, p.name))
    with ThreadPoolExecutor(max_workers=max(1, min(len(order), os.cpu_count() or 1))) as pool:
        return dict(zip(order, pool.map(_execute, order)))


def test_the_book_has_its_thirteen_chapters():
    assert [p.name[:2] for p in CHAPTERS] == [f"{k:02d}" for k in range(1, 14)]


@pytest.mark.parametrize("path", CHAPTERS, ids=lambda p: p.stem)
def test_chapter_executes_without_error(path, executed):
    notebook = executed[path]
    if isinstance(notebook, Exception):
        raise notebook
    code_cells = [c for c in notebook.cells if c.cell_type == "code"]
    assert code_cells, f"{path.name} has no code cell: every chapter computes what it shows"
    errors = [o for c in code_cells for o in c.get("outputs", []) if o.get("output_type") == "error"]
    assert not errors
    assert all(c.get("execution_count") for c in code_cells), "a code cell was not executed"


@pytest.mark.parametrize("path", CHAPTERS, ids=lambda p: p.stem)
def test_chapter_glues_the_numbers_its_prose_pastes(path, executed):
    """Each key of tests/test_prose_claims.py is glued when the chapter runs, as a plain number."""
    import ast

    from tests.test_prose_claims import CLAIMS

    notebook = executed[path]
    if isinstance(notebook, Exception):
        pytest.skip("the chapter did not execute (its own test fails)")
    glued = {}
    for cell in notebook.cells:
        for output in cell.get("outputs", []):
            name = output.get("metadata", {}).get("scrapbook", {}).get("name")
            if name:
                prefix = output["metadata"]["scrapbook"].get("mime_prefix", "")
                glued[name] = output["data"].get(prefix + "text/plain")
    for chapter, key, _, _ in CLAIMS:
        if chapter == path.name:
            assert key in glued, f"{path.name} does not glue {key}"
            value = ast.literal_eval(glued[key])    # '{glue:text}' formats only plain numbers
            assert isinstance(value, (int, float)), f"{key} is glued as {glued[key]!r}"
