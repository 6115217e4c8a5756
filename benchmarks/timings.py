"""Where readers and maintainers wait: the figures of issue 14, measured in one run.

Run as ``make timings`` (or ``python benchmarks/timings.py [--skip-make-test] [--skip PART ...]``).
Every figure printed comes from this run; nothing is read from earlier runs. This is a benchmark
script, not a test: it asserts nothing, it prints each figure beside its target.

Parts, in order:

notebooks (target 1: each <= 20 s, all <= 120 s)
    Every notebook page of the book (the ``_toc.yml`` order: chapters, the notation page, the
    appendix, the exercise pages with their solutions) executed top to bottom by nbclient in a fresh
    kernel, in its own folder, one after another: the wait of a reader who runs one page. Kernel
    start and imports are included; the part of the sum that is the kernels' start and stop alone
    (a page with one empty cell, times the pages) follows it. Then the book's execution as ``make
    book`` runs it (``book/_ext/execute_pages.py``: the pages a core each, nothing cached), wall
    time: the issue's own measure ("about 275 s of [make book] executing notebooks").
make-test (target 2: <= 7 min from a clean clone, every notebook executed once)
    ``git clone`` of this repository into a temporary folder, then ``make test`` there, timed: the
    virtual environment's installation (``make .venv/.installed``, from pip's cache) and the test
    run separately. Needs Chromium for the site test, as ``make test`` does. About 7 minutes.
cli (target 3: ``closedloop simulate --case 2`` <= 0.4 s wall)
    ``benchmarks/cli_time.py``.
output-grid (target 4: 10 000 outputs cost <= 1.5 x no outputs)
    ``benchmarks/output_grid_cost.py``.
basin (target 6: 100 x 100 in < 60 s)
    ``benchmarks/basin.py --size 100``.

The speed against the sympy.physics.mechanics baseline is its own script,
``benchmarks/speed_vs_baseline.py``, run by ``make speed``: it takes longer than all of these, and it
prints the measured ratio with the configurations compared, not a target.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PARTS = ("notebooks", "make-test", "cli", "output-grid", "basin")
#: The scripts of the other parts, with their arguments.
SCRIPTS = {
    "cli": ["benchmarks/cli_time.py"],
    "output-grid": ["benchmarks/output_grid_cost.py"],
    "basin": ["benchmarks/basin.py", "--size", "100", "--sample", "0"],
}


def notebook_pages():
    """The book's notebook pages in table-of-contents order (paths relative to ROOT), as make book finds them."""
    return [path.relative_to(ROOT) for path in _execute_pages().notebook_pages()]


def _execute_pages():
    """``book/_ext/execute_pages.py``, which make book runs before the build."""
    sys.path.insert(0, str(ROOT / "book" / "_ext"))
    import execute_pages

    return execute_pages


def time_notebook(path):
    """Wall time [s] of one execution of the notebook at ``path``, kernel start included."""
    import jupytext

    return _time_execution(jupytext.read(ROOT / path), (ROOT / path).parent)


def time_empty_page():
    """Wall time [s] of a notebook with one empty cell: the kernel's start and stop, the floor of every page."""
    import nbformat

    notebook = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("pass")])
    return min(_time_execution(notebook, ROOT) for _ in range(3))


def _time_execution(notebook, folder):
    import nbclient

    start = time.perf_counter()
    nbclient.NotebookClient(notebook, timeout=600, kernel_name="python3",
                            resources={"metadata": {"path": str(folder)}}).execute(
        stderr=subprocess.DEVNULL)              # the kernel's start-up notices, not the notebook's output
    return time.perf_counter() - start


def notebooks():
    print("== notebooks: execution of every page, kernel start included (target: each <= 20 s, all <= 120 s)")
    env_path = os.environ.get("PYTHONPATH", "")
    os.environ["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT / "src"), env_path) if p)
    times = {}
    for path in notebook_pages():
        times[path] = time_notebook(path)
        flag = "" if times[path] <= 20 else "   over 20 s"
        print(f"  {times[path]:6.1f} s  {path}{flag}", flush=True)
    total = sum(times.values())
    slowest = max(times, key=times.get)
    print(f"  one after another: {total:.0f} s over {len(times)} notebooks; slowest {times[slowest]:.1f} s "
          f"({slowest})")
    floor = time_empty_page()
    print(f"  of which the kernels' start and stop: {len(times) * floor:.0f} s ({floor:.2f} s a page, the best of "
          "three runs of a page with one empty cell)")
    execute_pages = _execute_pages()
    pages = execute_pages.notebook_pages()
    start = time.perf_counter()
    failed = [path.relative_to(ROOT) for path, notebook, _, _ in execute_pages.execute(pages, 600) if notebook is None]
    wall = time.perf_counter() - start
    print(f"  the book's execution as make book runs it, {execute_pages.workers(len(pages))} pages at a time: "
          f"{wall:.0f} s wall "
          f"(target <= 120 s){'; failed: ' + ', '.join(map(str, failed)) if failed else ''}")


def make_test():
    print("== make test from a clean clone (target <= 7 min, every notebook executed once)")
    sys.path.insert(0, str(ROOT / "book" / "print"))
    from print_pdf import chromium                  # the browser of the site test and the PDF

    browser = chromium()
    if not Path(browser).exists():
        print("  note: no Chromium here; make test will try to install chromium-headless-shell, or skip the site "
              "test and the PDF")
    elif not browser.endswith("chromium-headless-shell"):
        print(f"  note: the browser here is {browser}; make test will try to install chromium-headless-shell (the "
              "site test and the PDF take twice the CPU time with the whole chromium)")
    folder = Path(tempfile.mkdtemp(prefix="closedloop-clone-"))
    try:
        subprocess.run(["git", "clone", "-q", str(ROOT), str(folder / "repo")], check=True)
        repo = folder / "repo"
        start = time.perf_counter()
        subprocess.run(["make", "-s", ".venv/.installed"], cwd=repo, check=True, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
        install = time.perf_counter() - start
        start = time.perf_counter()
        done = subprocess.run(["make", "-s", "test"], cwd=repo, capture_output=True, text=True)
        tests = time.perf_counter() - start
        summary = [line for line in done.stdout.splitlines() if " passed" in line or " failed" in line]
        print(f"  virtual environment: {install:.0f} s (pip, from its cache)")
        print(f"  make test: {tests:.0f} s = {tests / 60:.1f} min (target <= 7 min), exit {done.returncode}")
        print(f"  {summary[-1].strip('= ') if summary else done.stdout[-500:]}")
        for line in done.stdout.splitlines():           # which tests failed, if any
            if line.startswith(("FAILED ", "ERROR ")):
                print(f"  {line}")
        log = repo / "_build" / "test-build.log"       # the session's make book: who executed the pages
        if log.exists():
            text = log.read_text()
            print(f"  pages executed: {_execute_pages().announced_count(text) or 0} before the build (a core each), "
                  f"{text.count('Executing notebook')} by the build itself")
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def script(part):
    arguments = SCRIPTS[part]
    print(f"== {part}: {' '.join(arguments)}", flush=True)
    if not (ROOT / arguments[0]).exists():
        print(f"  {arguments[0]} is missing")
        return
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (str(ROOT / "src"),
                                                                 os.environ.get("PYTHONPATH", "")) if p))
    subprocess.run([sys.executable, *arguments], cwd=ROOT, env=env, check=False)


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--skip", nargs="*", default=[], choices=PARTS, help="parts not to run")
    parser.add_argument("--skip-make-test", action="store_true", help="the same as --skip make-test")
    args = parser.parse_args(argv)
    skipped = set(args.skip) | ({"make-test"} if args.skip_make_test else set())
    print(f"closedloop timings, {time.strftime('%Y-%m-%d %H:%M')}, {os.cpu_count()} cores, "
          f"load average {os.getloadavg()[0]:.2f}")
    for part in PARTS:
        if part in skipped:
            continue
        if part == "notebooks":
            notebooks()
        elif part == "make-test":
            make_test()
        else:
            script(part)


if __name__ == "__main__":
    main()
