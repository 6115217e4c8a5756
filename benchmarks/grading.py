"""Time to grade one submission (exercises/grade.py), against running the same notebook plainly.

Run as ``python benchmarks/grading.py [--chapters 01 06] [--repeats 3]``.
Every figure printed comes from this run. This is a benchmark script, not a test: it asserts nothing.

What is measured, per chapter, on the reference solution of its exercise page (the page with its
solutions, converted by jupytext), the two ways interleaved, the median of ``--repeats``:

graded
    ``grade.grade_submission``: the copy into a fresh folder, the kernel's start behind the
    isolation chosen here, every cell, reading the checks' log (what one row of a gradebook costs);
plain
    the same notebook run by nbclient in a folder beside a copy of ``checking``, with no isolation
    (what a student's "Run all" costs).
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

EXERCISES = Path(__file__).resolve().parents[1] / "exercises"
sys.path.insert(0, str(EXERCISES))
import grade  # noqa: E402


def reference(chapter, folder):
    """Write chapter ``chapter``'s reference solution as .ipynb into ``folder``; return its path."""
    import jupytext

    source = next(EXERCISES.glob(f"{chapter}-*.md"))
    target = folder / f"{source.stem}.ipynb"
    jupytext.write(jupytext.read(source), target, fmt="ipynb")
    return target


def graded_seconds(path, chapter, isolated):
    start = time.perf_counter()
    graded = grade.grade_submission(path.name, path, "", chapter, grade.labels_of(chapter), 600, isolated,
                                    EXERCISES / "checking")
    seconds = time.perf_counter() - start
    if graded.status != "ok" or graded.total != len(graded.outcomes):
        raise RuntimeError(f"the reference of chapter {chapter} was graded {graded}")
    return seconds


def plain_seconds(path):
    import nbclient
    import nbformat

    start = time.perf_counter()
    folder = Path(tempfile.mkdtemp(prefix="plain-run-"))
    try:
        shutil.copytree(EXERCISES / "checking", folder / "checking", ignore=shutil.ignore_patterns("__pycache__"))
        notebook = nbformat.read(path, as_version=4)
        nbclient.NotebookClient(notebook, timeout=600, kernel_name="python3",
                                resources={"metadata": {"path": str(folder)}}).execute()
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    return time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--chapters", nargs="+", default=["01", "06"])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    isolated = grade.isolation()
    print(f"isolation: {isolated.name}; median of {args.repeats}, the two ways interleaved")
    print(f"{'chapter':>7}  {'graded [s]':>10}  {'plain [s]':>9}  {'graded / plain':>14}")
    with tempfile.TemporaryDirectory() as scratch:
        for chapter in args.chapters:
            path = reference(chapter, Path(scratch))
            graded, plain = [], []
            for _ in range(args.repeats):
                graded.append(graded_seconds(path, chapter, isolated))
                plain.append(plain_seconds(path))
            g, p = statistics.median(graded), statistics.median(plain)
            print(f"{chapter:>7}  {g:10.2f}  {p:9.2f}  {g / p:14.2f}")


if __name__ == "__main__":
    main()
