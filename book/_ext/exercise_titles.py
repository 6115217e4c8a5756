"""Show an exercise's number as its number: "Exercise 6.3 (title)", not "Exercise (6.3: title)".

Every ``{exercise}`` of the book is ``:nonumber:`` and carries its number in its title
("6.3: title"), so that the chapter, its exercise page, the student notebook and
``check("6.3", ...)`` share one numbering (sphinx-exercise would number through the book).
sphinx-exercise shows such a title in parentheses; this post-transform, run after its own
(priorities 20-22), moves the number out of them, in exercises and in their solutions' titles.
"""

import re

from docutils import nodes
from sphinx.transforms.post_transforms import SphinxPostTransform

NUMBER = re.compile(r"^(\d+(?:\.\d+)+):\s*")


class NumberExerciseTitles(SphinxPostTransform):
    default_priority = 30

    def run(self, **kwargs):
        for title in list(self.document.findall(nodes.title)):
            parent = title.parent
            if parent is not None and {"exercise", "solution", "solution-start", "exercise-start"} & \
                    set(parent.get("classes", [])):
                self.renumber(title)

    def renumber(self, element):
        """In ``element``'s children (and theirs): " (" then "6.3: rest" becomes " 6.3 (" then "rest"."""
        children = element.children
        for i, child in enumerate(children):
            if isinstance(child, nodes.Element):
                self.renumber(child)
            elif str(child).endswith(" (") and i + 1 < len(children) and isinstance(children[i + 1], nodes.Text):
                match = NUMBER.match(str(children[i + 1]))
                if match:
                    children[i] = nodes.Text(str(child)[:-2] + f" {match.group(1)} (")
                    children[i + 1] = nodes.Text(str(children[i + 1])[match.end():])
                    children[i].parent = children[i + 1].parent = element


def setup(app):
    app.add_post_transform(NumberExerciseTitles)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
