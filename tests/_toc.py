"""The book's pages as ``_toc.yml`` lists them, for the tests that read the built book."""

from pathlib import Path

import yaml

TOC = Path(__file__).resolve().parents[1] / "_toc.yml"


def toc_parts():
    """The parts of ``_toc.yml``, each a dict with its ``caption``, ``chapters`` and options."""
    return yaml.safe_load(TOC.read_text())["parts"]


def toc_documents():
    """[(docname, numbered)] of every page after the root, in the order of ``_toc.yml``."""
    return [(chapter["file"], bool(part.get("numbered"))) for part in toc_parts() for chapter in part["chapters"]]


def toc_pages():
    """Every page's docname, the root first, in the order of ``_toc.yml``."""
    return [yaml.safe_load(TOC.read_text())["root"]] + [name for name, _ in toc_documents()]
