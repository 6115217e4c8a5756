"""The pages executed before the build (book/_ext/execute_pages.py) are the ones the build looks up.

``make book`` executes the pages a core each into myst-nb's execution cache, and the build then takes
every page from that cache. The cache finds a page by a hash of its code cells, their metadata and the
kernelspec; a notebook stored with anything more in a code cell's metadata (nbclient's execution times,
for one) is never found, and the build quietly executes every page a second time. These tests execute a
real page and look it up exactly as the build does.
"""

import importlib.util
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import psutil
import pytest

ROOT = Path(__file__).resolve().parents[1]
#: A short page with code cells, one of them with tags and an image's alt text in its metadata.
PAGE = ROOT / "chapters" / "01-closed-loop-systems.md"


@pytest.fixture(scope="module")
def execute_pages():
    spec = importlib.util.spec_from_file_location("execute_pages", ROOT / "book" / "_ext" / "execute_pages.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def executed(execute_pages):
    path, notebook, seconds, error = execute_pages.execute_page(PAGE, timeout=120)
    assert error is None, error
    return notebook


def test_an_executed_page_is_found_by_the_build(execute_pages, executed, tmp_path):
    from jupyter_cache import get_cache
    from jupyter_cache.base import CacheBundleIn

    cache = get_cache(str(tmp_path / "cache"))
    with pytest.raises(KeyError):                               # an empty cache finds nothing
        cache.match_cache_notebook(execute_pages.read_page(PAGE))
    assert execute_pages.cached_record(cache, execute_pages.read_page(PAGE)) is None
    record = cache.add_nb_to_project(str(PAGE), read_data={"type": "plugin", "name": "myst_nb_md"})
    stored = cache.cache_notebook_bundle(CacheBundleIn(executed, record.uri), check_validity=False, overwrite=True)
    assert cache.match_cache_notebook(execute_pages.read_page(PAGE)).pk == stored.pk
    assert execute_pages.cached_record(cache, execute_pages.read_page(PAGE)).pk == stored.pk


def test_an_executed_page_carries_outputs_and_no_execution_times(execute_pages, executed):
    code = [cell for cell in executed.cells if cell.cell_type == "code"]
    assert any(cell.outputs for cell in code)
    assert [cell for cell in code if "execution" in cell.metadata] == []
    # the metadata the page's author wrote are kept: the build renders them (tags, alt text)
    assert [cell.metadata for cell in code] == [cell.metadata for cell in execute_pages.read_page(PAGE).cells
                                                if cell.cell_type == "code"]


def test_the_build_of_this_session_executed_no_page_itself(execute_pages, built_site):
    """``make book`` (the session's build, conftest.py): the pages are executed once, before the build,
    and the build itself executes none (myst-nb logs "Executing notebook" for each page it executes)."""
    from .conftest import BUILD_LOG

    if os.environ.get("CLOSEDLOOP_SITE_BUILT") == "1" or not BUILD_LOG.exists():
        pytest.skip("the site was built before this session: its build log is not this session's")
    log = BUILD_LOG.read_text()
    assert "Executing notebook" not in log, [line for line in log.splitlines() if "Executing notebook" in line]
    executed = execute_pages.announced_count(log)
    if executed is not None:           # a build from scratch: the build found every page executed before it
        found = set(re.findall(r"^(\S+): Using cached notebook", log, re.M))
        assert len(found) == executed, sorted(found)


# -- running it on a book of its own --------------------------------------------------------------
PAGE_TEMPLATE = """---
jupytext:
  text_representation:
    extension: .md
    format_name: myst
kernelspec:
  display_name: Python 3
  language: python
  name: python3
---

# {title}

```{{code-cell}} ipython3
{code}
```
"""


def small_book(folder, pages):
    """A book in ``folder`` of ``pages`` (``{name: code of its one cell}``), with its own copy of
    execute_pages.py (whose root is the book's folder) and an empty execution cache: the command that runs it."""
    (folder / "book" / "_ext").mkdir(parents=True)
    script = ROOT / "book" / "_ext" / "execute_pages.py"
    (folder / "book" / "_ext" / "execute_pages.py").write_text(script.read_text())
    (folder / "_config.yml").write_text("execute:\n  cache: _build/.jupyter_cache\n  timeout: 300\n")
    (folder / "_toc.yml").write_text("format: jb-book\nroot: intro\nparts:\n  - chapters:\n"
                                     + "".join(f"    - file: {name}\n" for name in pages))
    (folder / "intro.md").write_text("# A book\n")
    for name, code in pages.items():
        (folder / f"{name}.md").write_text(PAGE_TEMPLATE.format(title=name, code=code))
    return [sys.executable, "book/_ext/execute_pages.py"]


def test_a_failing_page_is_named_with_its_error_in_plain_text_and_not_cached(tmp_path):
    command = small_book(tmp_path, {"broken": 'raise ValueError("a bug of the page")'})
    done = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stdout + done.stderr
    line = next(line for line in done.stdout.splitlines() if line.startswith("  broken.md: "))
    assert re.fullmatch(r"  broken\.md: failed after [0-9.]+ s \(ValueError: a bug of the page\); "
                        r"the build executes it again", line), line      # no terminal colour codes in it
    again = subprocess.run(command, cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert "1 pages to execute" in again.stdout                            # it was not cached


@pytest.mark.parametrize("signum, to_group", [(signal.SIGINT, True), (signal.SIGTERM, False)],
                         ids=["ctrl-c", "sigterm"])
def test_a_signal_stops_the_execution_with_its_workers_and_kernels(tmp_path, signum, to_group):
    """Ctrl-C (SIGINT to the whole process group, as a terminal sends it) or SIGTERM to the script alone,
    while the pages run: it stops at once, says so, and leaves no worker, no kernel and no socket folder.  Before,
    nbclient's handler in each worker shut only the page's kernel down, and the workers went on to the
    next pages.  (After a Ctrl-C the kernels may log their end, a KeyboardInterrupt or a closed socket: the
    worker's nbclient handler interrupts its kernel and starts to shut it down as the worker is killed.)"""
    sleeping = 'import pathlib\nimport time\n\npathlib.Path("{}.running").touch()\ntime.sleep(120)'
    command = small_book(tmp_path, {name: sleeping.format(name) for name in ("one", "two")})
    running = min(2, os.cpu_count() or 1)                 # the pages run a core each
    # where the kernels' socket folders go: a short path, as a Unix socket's may not exceed 107 bytes
    temporary = Path(tempfile.mkdtemp(prefix="cl-"))
    # SIGINT at its default, as in a terminal (a shell's background job starts with it ignored)
    process = subprocess.Popen(command, cwd=tmp_path, env={**os.environ, "TMPDIR": str(temporary)},
                               stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True,
                               preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    seen = []
    try:
        deadline = time.monotonic() + 90
        while sum((tmp_path / f"{name}.running").exists() for name in ("one", "two")) < running:
            assert time.monotonic() < deadline and process.poll() is None, "the pages did not start"
            time.sleep(0.2)
        seen = psutil.Process(process.pid).children(recursive=True)      # the workers, each with its kernel
        assert sum("ipykernel_launcher" in " ".join(_command(p)) for p in seen) == running
        if to_group:
            os.killpg(process.pid, signum)
        else:
            process.send_signal(signum)
        out, _ = process.communicate(timeout=20)
    finally:
        try:                                              # what is left of its group, if the test failed
            os.killpg(process.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        leftovers = list(temporary.iterdir())
        shutil.rmtree(temporary, ignore_errors=True)
    assert process.returncode == 128 + signum, out
    assert f"execute_pages: stopped by {signal.Signals(signum).name}; 0 of 2 pages executed and cached" in out
    # no traceback of the script's own, nor of its pool's thread (the kernels may log their end: see above)
    assert 'execute_pages.py", line' not in out and "concurrent/futures" not in out, out.replace("\n", "\n| ")
    _, alive = psutil.wait_procs(seen, timeout=10)        # the kernels leave when their workers do
    alive = [p for p in alive if _status(p) != psutil.STATUS_ZOMBIE]    # ended, not yet reaped by an init
    assert not alive, f"outlived the script: {[' '.join(_command(p)) for p in alive]}"
    assert leftovers == [], "the kernels' socket folders were left behind"


def test_a_stop_while_a_page_is_stored_comes_once_it_is_stored(execute_pages):
    """A record without its notebook in jupyter-cache would be taken for the page by every later build."""
    stops, done = execute_pages._Stops(), []
    with pytest.raises(execute_pages.Stopped) as raised:
        with stops.held_back():
            stops.handler(signal.SIGTERM, None)            # as the signal calls it, while the page is stored
            done.append("stored")
    assert done == ["stored"] and raised.value.signal == signal.SIGTERM
    with pytest.raises(execute_pages.Stopped) as raised:
        execute_pages._Stops().handler(signal.SIGINT, None)    # between pages: at once
    assert raised.value.signal == signal.SIGINT


def _command(process):
    try:
        return process.cmdline()
    except psutil.Error:                                  # it has just ended
        return []


def _status(process):
    try:
        return process.status()
    except psutil.Error:
        return psutil.STATUS_DEAD
