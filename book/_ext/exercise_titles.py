"""Show an exercise's number as its number: "Exercise 6.3 (title)", not "Exercise (6.3: title)".

Every ``{exercise}`` of the book is ``:nonumber:`` and carries its number in its title
("6.3: title"), so that the chapter, its exercise page, the student notebook and
``check("6.3", ...)`` share one numbering (sphinx-exercise would number through the book).
sphinx-exercise shows such a title in parentheses; this post-transform, run after its own
(priorities 20-22), moves the number out of them, in exercises and in their solutions' titles.

Each exercise's title then ends with its expected time and difficulty, "· 10 min · easy", in the
edition's language (``exercises/effort.yml``, ``plain_notebook.exercise_effort``); a solution's title
does not repeat them.
"""

import re

from docutils import nodes
from sphinx.transforms import SphinxTransform
from sphinx.transforms.post_transforms import SphinxPostTransform

NUMBER = re.compile(r"^(\d+(?:\.\d+)+):\s*")
#: The number in a renumbered title: "Exercise 6.3 (title)", "Bài tập 6.3 (...)".
NUMBER_IN_TITLE = re.compile(r"(\d+(?:\.\d+)+) \(")


def translatable(directive):
    """``directive`` (sphinx-exercise's exercise directives) with its title offered for translation.

    sphinx-exercise builds an exercise's title (its "subtitle") with no source text or location, so
    Sphinx's gettext passes it over and a translated edition would show it in English. The subclass
    gives the title node the directive's argument as its source text, and its file and line.
    """
    from sphinx_exercise.nodes import exercise_subtitle

    class Translatable(directive):
        def run(self):
            result = super().run()
            for node in result:
                for title in node.findall(exercise_subtitle):
                    title.rawsource = self.arguments[0]
                    title.source, title.line = self.get_source_info()
            return result

    Translatable.__name__ = f"Translatable{directive.__name__}"
    return Translatable


class RegisterTranslatedExercises(SphinxTransform):
    """After Sphinx's Locale transform (priority 20): the registry holds each exercise as translated.

    sphinx-exercise keeps a copy of each exercise, made while the page is parsed, and builds its
    solutions' titles ("Solution to Exercise 6.3 (title)") from that copy: in a translated edition
    they would show the English title. The copy is renewed once the page is translated.
    """

    default_priority = 21

    def apply(self, **kwargs):
        from sphinx_exercise.nodes import exercise_enumerable_node, exercise_node

        registry = getattr(self.env, "sphinx_exercise_registry", {})
        for node in self.document.findall(lambda n: isinstance(n, (exercise_node, exercise_enumerable_node))):
            entry = registry.get(node.get("label"))
            if entry is not None and entry.get("docname") == self.env.docname:
                entry["node"] = node.deepcopy()


class OfferExerciseTitles(SphinxPostTransform):
    """For the gettext builder only: keep each exercise's title as a message.

    Sphinx's gettext reads the messages after the post-transforms, and sphinx-exercise's (priority
    20) moves the title's words into a new title with no source text. A copy of the source text,
    made just before, is what gettext reads; the HTML builders never see it. The translation itself
    is applied to the title when the page is read, before any post-transform.
    """

    default_priority = 19
    builders = ("gettext",)

    def run(self, **kwargs):
        from sphinx_exercise.nodes import exercise_subtitle

        for title in list(self.document.findall(exercise_subtitle)):
            if title.rawsource and title.source:
                copy = nodes.paragraph(title.rawsource, title.rawsource)
                copy.source, copy.line = title.source, title.line
                copy.uid = getattr(title, "uid", "")        # the gettext catalogue keeps only nodes with one
                title.parent.parent.append(copy)


class NumberExerciseTitles(SphinxPostTransform):
    default_priority = 30

    def run(self, **kwargs):
        for title in list(self.document.findall(nodes.title)):
            parent = title.parent
            classes = set(parent.get("classes", [])) if parent is not None else set()
            if {"exercise", "solution", "solution-start", "exercise-start"} & classes:
                self.renumber(title)
            if {"exercise", "exercise-start"} & classes:
                self.add_effort(title)

    def add_effort(self, title):
        """" · 10 min · easy" after an exercise's title (``exercises/effort.yml``)."""
        from plain_notebook import exercise_effort

        number = NUMBER_IN_TITLE.search(title.astext())
        if number:
            effort = " · " + exercise_effort(number.group(1), (self.config.language or "en").split("_")[0])
            title += nodes.inline(effort, effort, classes=["exercise-effort"])

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
    from sphinx_exercise.directive import ExerciseDirective, ExerciseStartDirective

    app.setup_extension("sphinx_exercise")
    app.add_directive("exercise", translatable(ExerciseDirective), override=True)
    app.add_directive("exercise-start", translatable(ExerciseStartDirective), override=True)
    app.add_transform(RegisterTranslatedExercises)
    app.add_post_transform(OfferExerciseTitles)
    app.add_post_transform(NumberExerciseTitles)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
