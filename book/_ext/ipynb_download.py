"""Offer each chapter as an executed .ipynb in the page's download menu.

sphinx-book-theme adds that entry only when a launch service (Binder, Colab,
Thebe, ...) is configured, and all of them need the network. This does the part
that needs none: put the executed notebook into ``_sources`` and tell the theme
where it is, as the theme's own launch code does.

MyST-NB writes the executed notebook to ``jupyter_execute``, but when the outputs
come from the execution cache (myst-nb 1.4) it writes the notebook *without* them.
So the outputs are merged back from the cache here.
"""

from contextlib import suppress
from pathlib import Path


def add_ipynb_source(app, pagename, templatename, context, doctree):
    import nbformat

    executed = Path(app.outdir).parent / "jupyter_execute" / f"{pagename}.ipynb"
    if doctree is None or not executed.exists():
        return
    notebook = nbformat.read(executed, as_version=4)
    if app.env.mystnb_config.execution_mode == "cache":
        from jupyter_cache import get_cache

        with suppress(KeyError):
            _, notebook = get_cache(app.env.mystnb_config.execution_cache_path).merge_match_into_notebook(notebook)
    target = Path(app.outdir) / "_sources" / f"{pagename}.ipynb"
    target.parent.mkdir(parents=True, exist_ok=True)
    nbformat.write(notebook, target)
    context["ipynb_source"] = f"{pagename}.ipynb"


def setup(app):
    # before sphinx-book-theme builds its header buttons (default priority 500)
    app.connect("html-page-context", add_ipynb_source, priority=400)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
