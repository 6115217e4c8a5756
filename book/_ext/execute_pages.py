"""Execute the book's notebook pages that the execution cache lacks, as many at a time as there are cores.

Jupyter Book 1 (myst-nb's ``cache`` mode) executes a page's notebook when Sphinx reads the page,
one page after another, so ``make book`` waited for the sum of all the pages' executions (about
150 s on this 2-core machine) with one core idle.  This script runs before the build and fills the
same execution cache with every page the cache lacks, executed in parallel; the build then finds
each page in the cache (its log says "Using cached notebook") and executes nothing.

It does what myst-nb does for one page, so that the build's lookup matches what it stores:

- the page is read by myst-nb's MyST reader (``read_myst_markdown_notebook``), whose notebook the
  cache hashes (its code cells, their metadata, the kernelspec);
- it is executed as jupyter-cache's ``single_nb_execution`` executes it (nbclient, in the page's
  folder, with the ``execute.timeout`` of ``_config.yml``), stopping at the first error, and without
  nbclient's timing metadata: the cache hashes each code cell's metadata, so a cell that carried its
  execution times would never match the page the build reads, and the build would execute every page
  again (it did, until this was found: the execution cost twice);
- it is cached with ``cache_notebook_bundle``, as myst-nb caches it.

A page whose execution fails is not cached: the build executes it again and reports the error as it
always has (``execute.raise_on_error``), so this script cannot hide a failure.  Each kernel talks to
its client through Unix sockets in a folder of its own: kernels started at the same moment over TCP
can be given the same port, and one of them dies.

Ctrl-C (SIGINT) or SIGTERM stops it at once: no page starts after it, the workers are ended, and
their kernels end with them (ipykernel leaves when its parent process does); the pages already
executed stay in the cache (a page being stored is stored first).  Without this, a stopped run
went on: nbclient's own handler of both signals in a worker only shuts that page's kernel down,
and the worker takes the next page; after a Ctrl-C the script waited for every page still to
come, and a SIGTERM ended the script alone, its workers going on without it.

    .venv/bin/python book/_ext/execute_pages.py        # make book and make pdf run it
"""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import re
import signal
import sys
import tempfile
import time
import traceback
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[2]


def notebook_pages():
    """The book's notebook pages (MyST Markdown with a jupytext header), in table-of-contents order."""
    toc = yaml.safe_load((ROOT / "_toc.yml").read_text())
    files = [toc["root"]] + [chapter["file"] for part in toc.get("parts", []) for chapter in part["chapters"]]
    paths = [ROOT / f"{name}.md" for name in files]
    return [path for path in paths if path.exists() and path.read_text().startswith("---\njupytext:")]


def read_page(path):
    """The page's notebook as myst-nb reads it for the build."""
    from myst_nb.core.read import read_myst_markdown_notebook
    from myst_parser.config.main import MdParserConfig

    return read_myst_markdown_notebook(path.read_text(), config=MdParserConfig(), add_source_map=True,
                                       path=str(path))


def execute_page(path, timeout, folder=None):
    """``(path, executed notebook or None, seconds, error text or None)`` of one page.

    As jupyter-cache's ``single_nb_execution`` (``nbclient.execute`` in the page's folder, the
    notebook's own ``execution`` metadata overriding the timeout), with a kernel of our own on Unix
    sockets in a temporary folder (inside ``folder`` if given), which the client shuts down at the
    end (``cleanup_kc``).
    """
    from jupyter_client.manager import AsyncKernelManager
    from nbclient import NotebookClient
    from nbclient.exceptions import CellExecutionError, CellTimeoutError

    notebook = read_page(path)
    options = notebook.metadata.get("execution", {})
    prefix = "closedloop-kernel-" if folder is None else "k-"      # short: a Unix socket's path has <= 107 bytes
    with tempfile.TemporaryDirectory(prefix=prefix, dir=folder) as sockets:
        kernel = AsyncKernelManager(kernel_name=notebook.metadata.kernelspec.name, transport="ipc",
                                    connection_file=os.path.join(sockets, "kernel.json"))
        client = NotebookClient(notebook, timeout=options.get("timeout", timeout),
                                allow_errors=options.get("allow_errors", False), record_timing=False,
                                resources={"metadata": {"path": str(path.parent)}}, km=kernel)
        start = time.perf_counter()
        try:
            client.execute(cleanup_kc=True)
        except (CellExecutionError, CellTimeoutError):
            return path, None, time.perf_counter() - start, traceback.format_exc()
    return path, notebook, time.perf_counter() - start, None


def execute(pages, timeout):
    """``execute_page`` of every page, a core each, the long pages first: its results as they come.

    If the caller is stopped while it waits (KeyboardInterrupt, or :class:`Stopped` from :func:`main`'s
    handler) or stops iterating, the workers are killed (their kernels follow them), no page
    starts after it, and the exception goes on.  The kernels' socket folders are in one temporary
    folder of this process, removed at the end: a killed worker cannot remove its own.
    """
    pages = sorted(pages, key=lambda path: path.stat().st_size, reverse=True)
    with tempfile.TemporaryDirectory(prefix="closedloop-") as folder, \
            ProcessPoolExecutor(max_workers=workers(len(pages)), initializer=_worker_signals) as pool:
        try:                                # from the first submission: it starts the workers
            futures = [pool.submit(execute_page, path, timeout, folder) for path in pages]
            for future in as_completed(futures):
                yield future.result()
        except BaseException:
            # the pool's workers (this process has no other children); the pool, broken, then fails the pages
            # not started (cancelling them first trips Python 3.11's pool: an InvalidStateError in its thread)
            for worker in multiprocessing.active_children():
                worker.kill()
            raise


def _worker_signals():
    """A worker's SIGINT and SIGTERM as Python's defaults (unless ignored): forked, it inherits :func:`main`'s
    handler, which is the script's alone; the script ends its workers itself."""
    for number, default in ((signal.SIGINT, signal.default_int_handler), (signal.SIGTERM, signal.SIG_DFL)):
        if signal.getsignal(number) is not signal.SIG_IGN:
            signal.signal(number, default)


def workers(count):
    """How many pages ``execute`` runs at a time, for ``count`` pages: one per core."""
    return max(1, min(count, os.cpu_count() or 1))


def cached_record(cache, notebook):
    """The cache's record of the page whose unexecuted notebook is ``notebook``, as the build looks it up,
    or None."""
    try:
        return cache.match_cache_notebook(notebook)
    except KeyError:
        return None


#: The terminal colour codes of an IPython traceback, which nbclient's error text carries.
_ANSI = re.compile(r"\x1b\[[0-9;]*m")
#: What ``main`` prints before it executes any page, and where a build log says how many it executed.
ANNOUNCEMENT = "execute_pages: {count} pages to execute, {workers} at a time"


def announced_count(log):
    """The number of pages ``main`` executed before the build whose log (text) is ``log``, or None if it
    executed none (every page was in the cache, or the script did not run)."""
    pattern = re.escape(ANNOUNCEMENT).replace(r"\{count\}", r"(\d+)").replace(r"\{workers\}", r"\d+")
    found = re.search(pattern, log)
    return int(found.group(1)) if found else None


def main():
    from jupyter_cache import get_cache

    settings = yaml.safe_load((ROOT / "_config.yml").read_text())["execute"]
    cache = get_cache(str(ROOT / settings["cache"]))
    pages = {path: read_page(path) for path in notebook_pages()}
    missing = [path for path, notebook in pages.items() if cached_record(cache, notebook) is None]
    if not missing:
        print("execute_pages: every page is in the execution cache")
        return 0
    print(ANNOUNCEMENT.format(count=len(missing), workers=workers(len(missing))), flush=True)
    start, cached, stops = time.perf_counter(), 0, _Stops()
    for number in (signal.SIGINT, signal.SIGTERM):
        if signal.getsignal(number) is not signal.SIG_IGN:       # nohup's stays ignored
            signal.signal(number, stops.handler)
    try:
        for result in execute(missing, settings.get("timeout", 30)):
            with stops.held_back():
                cached += _store(cache, pages, *result)
    except Stopped as stop:
        print(f"execute_pages: stopped by {signal.Signals(stop.signal).name}; {cached} of {len(missing)} pages "
              "executed and cached", flush=True)
        return 128 + stop.signal
    print(f"execute_pages: {time.perf_counter() - start:.0f} s wall for {len(missing)} pages", flush=True)
    return 0


class Stopped(BaseException):
    """SIGINT or SIGTERM reached :func:`main` (``signal``: its number); like KeyboardInterrupt, no
    ``except Exception`` on the way takes it for an error of its own."""

    def __init__(self, number):
        super().__init__(number)
        self.signal = number


class _Stops:
    """:func:`main`'s handler of SIGINT and SIGTERM: it raises :class:`Stopped`, except while a page is being
    stored (:meth:`held_back`), which is finished first.  A stop while jupyter-cache writes would leave a record
    without its notebook, which every later build would take for the page."""

    def __init__(self):
        self.storing, self.pending = False, None

    def handler(self, number, frame):
        if self.storing:
            self.pending = number
        else:
            raise Stopped(number)

    @contextlib.contextmanager
    def held_back(self):
        self.storing = True
        try:
            yield
        finally:
            self.storing = False
        if self.pending is not None:
            raise Stopped(self.pending)


def _store(cache, pages, path, notebook, seconds, error):
    """Cache one executed page as myst-nb would, and say how it went: True if the build will find it."""
    from jupyter_cache.base import CacheBundleIn

    name = path.relative_to(ROOT)
    if notebook is None:
        last = _ANSI.sub("", error).strip().splitlines()[-1] if error else "no reason given"
        print(f"  {name}: failed after {seconds:.1f} s ({last}); the build executes it again", flush=True)
        return False
    record = cache.add_nb_to_project(str(path), read_data={"type": "plugin", "name": "myst_nb_md"})
    stored = cache.cache_notebook_bundle(CacheBundleIn(notebook, record.uri, data={"execution_seconds": seconds}),
                                         check_validity=False, overwrite=True)
    found = cached_record(cache, pages[path])
    if found is None or found.pk != stored.pk:
        print(f"  {name}: executed in {seconds:.1f} s, but the build will not find it in the cache "
              "and executes it again", flush=True)
        return False
    print(f"  {name}: {seconds:.1f} s", flush=True)
    return True


if __name__ == "__main__":
    sys.exit(main())
