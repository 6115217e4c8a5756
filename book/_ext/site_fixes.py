"""Three fixes to what Jupyter Book 1.x writes around the pages.

**Thebe off.** Jupyter Book always loads sphinx-thebe. Under Sphinx 7 its inline config script
(``const THEBE_JS_URL = ...``) lands in every page twice, and the second copy is a JavaScript
error ("Identifier 'THEBE_JS_URL' has already been declared"). This book never runs code in the
page, so sphinx-thebe's page work (the config script, its loader, the per-page kernel settings)
is disconnected and its stylesheet dropped.

**The site's front page.** ``index.html`` is a redirect to the root page, written by
sphinx-external-toc as a bare ``<meta>`` refresh with no icon, so the browser asks for
``/favicon.ico``, which does not exist (a 404). The redirect is written here instead, as a small
HTML page that names the book's own icon; sphinx-external-toc leaves an existing index.html alone.

**The single-page build** (``--builder singlehtml``, which ``book/print/print_pdf.py`` prints to PDF).
Sphinx gives a builder the node handlers registered under its name, and only when there are none
under its name those of its format. sphinx-exercise registers handlers under ``singlehtml``, so
that builder no longer sees what other extensions registered under ``html`` only (MyST-NB's
``HideCodeCellNode``: "unknown node type"). The ``html`` handlers missing under ``singlehtml``
are copied there when the builder starts.
"""

import html
from pathlib import Path

THEBE_HANDLERS = {"init_thebe_core", "update_thebe_context"}


def write_front_page(app, exception):
    if exception is not None or app.builder.format != "html" or app.config.root_doc == "index":
        return
    target = html.escape(f"{app.config.root_doc}.html")
    title = html.escape(app.config.html_title or app.config.project or "")
    icon = (f'<link rel="icon" href="_static/{html.escape(Path(app.config.html_favicon).name)}">'
            if app.config.html_favicon else "")
    language = html.escape(app.config.language or "en")
    Path(app.outdir, "index.html").write_text(
        f'<!DOCTYPE html>\n<html lang="{language}"><head><meta charset="utf-8"><title>{title}</title>{icon}'
        f'<meta http-equiv="Refresh" content="0; url={target}"></head>\n'
        f'<body><p><a href="{target}">{title}</a></p></body></html>\n', encoding="utf-8")


def share_html_handlers(app):
    """Every node handler registered for ``html`` and not for ``singlehtml`` also for ``singlehtml``."""
    if app.builder.name != "singlehtml":
        return
    handlers = app.registry.translation_handlers
    single = handlers.setdefault("singlehtml", {})
    for node, visitors in handlers.get("html", {}).items():
        single.setdefault(node, visitors)


def setup(app):
    app.setup_extension("sphinx_thebe")
    for listeners in app.events.listeners.values():
        for listener in list(listeners):
            handler = listener.handler
            if handler.__module__ == "sphinx_thebe" and handler.__name__ in THEBE_HANDLERS:
                app.disconnect(listener.id)
    app.registry.css_files[:] = [(name, attributes) for name, attributes in app.registry.css_files
                                 if name != "sphinx-thebe.css"]
    app.connect("builder-inited", share_html_handlers)
    app.connect("build-finished", write_front_page, priority=400)    # before sphinx-external-toc's (500)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
