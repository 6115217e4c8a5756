"""Two fixes to what Jupyter Book 1.x writes around the pages.

**Thebe off.** Jupyter Book always loads sphinx-thebe. Under Sphinx 7 its inline config script
(``const THEBE_JS_URL = ...``) lands in every page twice, and the second copy is a JavaScript
error ("Identifier 'THEBE_JS_URL' has already been declared"). This book never runs code in the
page, so sphinx-thebe's page work (the config script, its loader, the per-page kernel settings)
is disconnected and its stylesheet dropped.

**The site's front page.** ``index.html`` is a redirect to the root page, written by
sphinx-external-toc as a bare ``<meta>`` refresh with no icon, so the browser asks for
``/favicon.ico``, which does not exist (a 404). The redirect is written here instead, as a small
HTML page that names the book's own icon; sphinx-external-toc leaves an existing index.html alone.
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
    Path(app.outdir, "index.html").write_text(
        f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8"><title>{title}</title>{icon}'
        f'<meta http-equiv="Refresh" content="0; url={target}"></head>\n'
        f'<body><p><a href="{target}">{title}</a></p></body></html>\n', encoding="utf-8")


def setup(app):
    app.setup_extension("sphinx_thebe")
    for listeners in app.events.listeners.values():
        for listener in list(listeners):
            handler = listener.handler
            if handler.__module__ == "sphinx_thebe" and handler.__name__ in THEBE_HANDLERS:
                app.disconnect(listener.id)
    app.registry.css_files[:] = [(name, attributes) for name, attributes in app.registry.css_files
                                 if name != "sphinx-thebe.css"]
    app.connect("build-finished", write_front_page, priority=400)    # before sphinx-external-toc's (500)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
