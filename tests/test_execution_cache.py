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
from pathlib import Path

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
