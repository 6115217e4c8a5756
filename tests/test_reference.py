"""The library reference (``book/reference.md``, built by Sphinx's autodoc from the docstrings).

Read in the built site (the ``built_site`` fixture of conftest.py): every name that a documented
module exports has an entry, every module the book's own code imports is documented, every link
between entries lands on one, and the docstrings stay English and out of the translation catalogues
while the page's own words are translated.
"""

import importlib
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGE = ROOT / "book" / "reference.md"
CATALOGUE = ROOT / "locales" / "vi" / "LC_MESSAGES" / "book" / "reference.po"
EDITIONS = ("", "vi/")


def documented_modules():
    """The modules the page documents, in its order (its ``.. library-module::`` lines)."""
    return re.findall(r"^\.\. library-module:: (\S+)", PAGE.read_text(encoding="utf-8"), flags=re.MULTILINE)


def imported_modules():
    """Every ``closedloop`` module that a chapter, an exercise notebook or a page of the book imports."""
    sources = [*ROOT.glob("chapters/*.md"), *ROOT.glob("exercises/*.md"), *ROOT.glob("book/*.md")]
    found = set()
    for path in sources:
        text = path.read_text(encoding="utf-8")
        found.update(re.findall(r"^\s*from (closedloop[\w.]*) import", text, flags=re.MULTILINE))
        found.update(re.findall(r"^\s*import (closedloop[\w.]*)", text, flags=re.MULTILINE))
    return found


def entry_ids(edition, built_site):
    html = (built_site / edition / "book" / "reference.html").read_text(encoding="utf-8")
    return set(re.findall(r'<dt class="sig[^"]*" id="([^"]+)"', html)), html


def text_of(html):
    """A page's text, its typographic apostrophes as typed (Sphinx writes ’ for ')."""
    from bs4 import BeautifulSoup

    return " ".join(BeautifulSoup(html, "html.parser").get_text(" ").split()).replace("\u2019", "'")


def simulate_summary():
    return importlib.import_module("closedloop").simulate.__doc__.strip().splitlines()[0]


def test_the_page_documents_modules():
    """The page's list can be wrong: a module that does not exist, or one listed twice."""
    modules = documented_modules()
    assert len(modules) >= 10 and len(set(modules)) == len(modules)
    for module in modules:
        importlib.import_module(module)


def test_every_module_the_book_imports_is_documented():
    imported = imported_modules()
    assert "closedloop.slider_crank" in imported and "closedloop" in imported   # the scan reads the pages
    assert sorted(imported - set(documented_modules())) == []


@pytest.mark.parametrize("edition", EDITIONS)
def test_every_exported_name_has_an_entry(built_site, edition):
    """Each name in a documented module's ``__all__`` has an entry: under that module, or, if
    ``closedloop`` itself exports the same object, under ``closedloop`` (where it is documented once)."""
    ids, _ = entry_ids(edition, built_site)
    top = importlib.import_module("closedloop")
    missing, counted = [], 0
    for module_name in documented_modules():
        module = importlib.import_module(module_name)
        for name in module.__all__:
            counted += 1
            obj = getattr(module, name)
            above = name in top.__all__ and getattr(top, name, None) is obj
            if f"{module_name}.{name}" not in ids and not (above and f"closedloop.{name}" in ids):
                missing.append(f"{module_name}.{name}")
    assert counted > 100
    assert missing == []


@pytest.mark.parametrize("edition", EDITIONS)
def test_every_link_between_entries_lands_on_one(built_site, edition):
    """A docstring that names another documented object links to it: the links exist, and each
    lands on an entry of the page."""
    ids, html = entry_ids(edition, built_site)
    targets = re.findall(r'<a class="reference internal" href="#(closedloop[^"]*)"', html)
    assert len(targets) > 50
    assert sorted(set(targets) - ids) == []


def test_each_object_is_documented_once(built_site):
    """``simulate`` under ``closedloop`` only, not again under ``closedloop.simulation``."""
    ids, html = entry_ids("", built_site)
    assert "closedloop.simulate" in ids and "closedloop.simulation.simulate" not in ids
    assert text_of(html).count(simulate_summary()) == 1


def test_the_docstrings_stay_english_and_out_of_the_catalogue(built_site):
    """The Vietnamese page shows simulate's docstring as the English page does, and its catalogue
    holds the page's own words only (translated, as every catalogue's are), no docstring."""
    from babel.messages.pofile import read_po

    _, english = entry_ids("", built_site)
    _, vietnamese = entry_ids("vi/", built_site)
    assert simulate_summary() in text_of(english) and simulate_summary() in text_of(vietnamese)
    with CATALOGUE.open("rb") as file:
        messages = [message for message in read_po(file) if message.id]
    first_lines = {obj.__doc__.strip().splitlines()[0] for module in documented_modules()
                   for obj in map(importlib.import_module(module).__dict__.get, importlib.import_module(module).__all__)
                   if callable(obj) and obj.__doc__}
    assert len(first_lines) > 100
    assert [message.id for message in messages if any(line in message.id for line in first_lines)] == []
    assert 5 <= len(messages) <= 20
    assert "Tra cứu thư viện" in vietnamese
