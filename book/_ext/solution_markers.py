"""Keep the solution markers of the exercise notebooks out of the built pages.

A solution's code cell holds lines that only ``exercises/make_student.py`` reads:
``# BEGIN SOLUTION``, ``# STUDENT: answer = ...`` and ``# END SOLUTION``. They stay in
the source, and the cell is executed as written (they are comments). Here they are
removed from the code that the page displays, after MyST-NB has turned each cell's
source into a literal block.
"""

from docutils import nodes

from plain_notebook import MARKER


def strip_displayed_markers(app, doctree):
    for block in list(doctree.findall(nodes.literal_block)):
        text = block.astext()
        if not MARKER.search(text):
            continue
        shown = MARKER.sub("", text).rstrip("\n")
        block.rawsource = shown
        block.children = []
        block += nodes.Text(shown)


def setup(app):
    app.connect("doctree-read", strip_displayed_markers)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
