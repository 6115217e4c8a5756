"""Ship BokehJS with the site, for the interactive figures (closedloop.plotting.interactive).

The installed Bokeh's own ``bokeh.min.js`` is copied into ``_static`` under a versioned name,
and a ``<script>`` for it is added to exactly the pages that hold an interactive figure (an
element of class ``closedloop-bokeh``).  No page asks a CDN for anything, and the other pages
do not load the 1.3 MB of BokehJS.
"""

import shutil
from pathlib import Path

MARKER = 'class="closedloop-bokeh"'


def _js_name():
    import bokeh

    return f"bokeh-{bokeh.__version__}.min.js"


def add_bokeh_js(app, pagename, templatename, context, doctree):
    if MARKER in context.get("body", ""):
        app.add_js_file(_js_name())             # in this handler: for this page only


def copy_bokeh_js(app, exception):
    if exception is not None or app.builder.format != "html":
        return
    from closedloop.plotting.interactive import bokeh_js_file

    target = Path(app.outdir) / "_static" / _js_name()
    target.parent.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(bokeh_js_file(), target)


def setup(app):
    app.connect("html-page-context", add_bokeh_js)
    app.connect("build-finished", copy_bokeh_js)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
