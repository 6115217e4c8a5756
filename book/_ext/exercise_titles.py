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
            if parent is None or not {"exercise", "solution", "solution-start", "exercise-start"} & \
                    set(parent.get("classes", [])):
                continue
            for text in list(title.findall(nodes.Text)):
                following = text.parent.children[text.parent.index(text) + 1:] if text.parent else []
                if str(text).endswith(" (") and following and isinstance(following[0], nodes.Text):
                    match = NUMBER.match(str(following[0]))
                    if match:
                        text.parent.replace(text, nodes.Text(str(text)[:-2] + f" {match.group(1)} ("))
                        following[0].parent.replace(following[0], nodes.Text(str(following[0])[match.end():]))


def setup(app):
    app.add_post_transform(NumberExerciseTitles)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
