"""Every chapter notebook executes from top to bottom without an error.

Chapters are MyST Markdown notebooks; nbmake cannot read them, so jupytext turns
each into a notebook and nbclient runs it in a fresh kernel, from the repository root.
"""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CHAPTERS = sorted((ROOT / "chapters").glob("*.md"))


def test_the_book_has_its_thirteen_chapters():
    assert [p.name[:2] for p in CHAPTERS] == [f"{k:02d}" for k in range(1, 14)]


@pytest.mark.parametrize("path", CHAPTERS, ids=lambda p: p.stem)
def test_chapter_executes_without_error(path):
    import jupytext
    import nbclient

    notebook = jupytext.read(path)
    code_cells = [c for c in notebook.cells if c.cell_type == "code"]
    assert code_cells, f"{path.name} has no code cell: every chapter computes what it shows"
    client = nbclient.NotebookClient(notebook, timeout=300, kernel_name="python3",
                                     resources={"metadata": {"path": str(ROOT)}})
    client.execute()                      # raises CellExecutionError, with the cell, on any error
    errors = [o for c in code_cells for o in c.get("outputs", []) if o.get("output_type") == "error"]
    assert not errors
    assert all(c.get("execution_count") for c in code_cells), "a code cell was not executed"
