"""Offer each chapter as an executed .ipynb in the page's download menu.

sphinx-book-theme adds that entry only when a launch service (Binder, Colab,
Thebe, ...) is configured, and all of them need the network. This does the part
that needs none: copy the notebook that MyST-NB executed into ``_sources`` and
tell the theme where it is, exactly as the theme's own launch code does.
"""

from pathlib import Path
from shutil import copy2


def add_ipynb_source(app, pagename, templatename, context, doctree):
    executed = Path(app.outdir).parent / "jupyter_execute" / f"{pagename}.ipynb"
    if doctree is None or not executed.exists():
        return
    target = Path(app.outdir) / "_sources" / f"{pagename}.ipynb"
    target.parent.mkdir(parents=True, exist_ok=True)
    copy2(executed, target)
    context["ipynb_source"] = f"{pagename}.ipynb"


def setup(app):
    # before sphinx-book-theme builds its header buttons (default priority 500)
    app.connect("html-page-context", add_ipynb_source, priority=400)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
