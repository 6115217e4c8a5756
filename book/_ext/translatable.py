"""What Sphinx's gettext leaves out of a translated edition of this book, put through the page's catalogue.

The English sources are the only source of content; a translated edition (``book/_ext/editions.py``)
takes every word from the page's gettext catalogue, ``locales/<language>/LC_MESSAGES/<page>.po``.
Sphinx's gettext handles paragraphs, titles and captions. Four kinds of text need this extension.

**Display equations and text diagrams, translated without being parsed again.** Sphinx translates a
"literal" node (a display equation, a code block, raw HTML) by parsing ``"::\\n\\n   " + msgstr``, the
reStructuredText for a literal block. Under MyST that text is a paragraph ``::`` followed by an
indented code block, and the node becomes ``::``: an equation whose ``\\text{...}`` was translated
rendered as ``\\[::\\]`` on the site and ``::`` in the PDF, while an equation left untranslated
(msgstr = msgid) showed correctly. Here the msgstr of such a node is its new text as it stands,
set before Sphinx's own ``Locale`` transform runs. A literal block with the class ``diagram``
(``{code-block} text`` with ``:class: diagram``, the intro's chapter diagram) is translatable too:
its lines are a message of the page.

**The words of code cells' outputs.** The editions share one execution, whose outputs are English.
The words a reader meets in them are messages of the page's catalogue, like its prose: the headings
and caption of a table (``closedloop.plotting.Table``), every ``alt``, ``title`` and ``aria-label`` of
an HTML output, the labels of the animations' player ("Once", "Loop", "Reflect"), and the ``alt`` of
every figure (``:mystnb: {image: {alt: ...}}``). The numbers in an HTML output's words are the
message's parameters ``{1}``, ``{2}``, ... (:func:`message_of`), so that a heading built from a
value ("rtol = atol = 1e-06", a table's caption) does not change its message when the value
changes; a translation keeps every parameter. An HTML output becomes a :class:`translated_html`
node, Sphinx's ``addnodes.translatable``: the gettext build extracts its words (``make translations``
writes them into the page's catalogue with everything else, and ``tests/test_translations.py`` lists
the untranslated ones by page), and the translated edition puts each translation back in place.
The gettext build is made to keep the outputs that the HTML build shows (MyST-NB would give it the
plain-text ones), so the two see the same words. Everything else in an output (printed text,
LaTeX, numbers, code, interactive figures) stays out of the catalogues: it is computed, and
changes whenever the computation does.

**The words a glue role pastes into the prose.** A sentence whose words depend on a value ("in
three of the four cases", a method's name) has them pasted by a ``{glue:text}`` role, from the
shared (English) execution. The gettext build reads each such paste as a message of the page's
catalogue (:class:`glued_words`, numbers as parameters), and a translated edition puts the
translation in after Sphinx's ``Locale`` has translated the paragraph around it
(:class:`TranslatePastedWords`).

**The interface around the pages.** The theme's and Sphinx's words ("On this page", "Link to this
heading", "previous page", the colour modes, the search page) are in the edition's interface
catalogue, ``locales/<language>/LC_MESSAGES/sphinx.po``: Sphinx's own text domain, which Sphinx reads
before its own translations and the theme's, so that its templates and writers take them from there.
The same catalogue serves the few words that are not passed through gettext, looked up here: the
values of ``title``, ``aria-label``, ``placeholder`` and ``data-bs-title`` that the theme and MyST-NB
write as they are ("Toggle primary sidebar", "Toggle hidden content", the search box's "Search this
book..."), MyST-NB's code-cell buttons ("Show code cell source" and its kin, written after the page
is translated), and the messages of the search page's script (``_static/translations.js``, which
Sphinx copies from its own translations).
"""

from __future__ import annotations

import html
import re
from pathlib import Path

from docutils import nodes
from sphinx import addnodes
from sphinx.locale import get_translation
from sphinx.transforms import SphinxTransform
from sphinx.transforms.post_transforms import SphinxPostTransform
from sphinx.util.nodes import LITERAL_TYPE_NODES, is_translatable

SOURCE_LANGUAGE = "en"
#: The text domain of the interface catalogue, ``locales/<language>/LC_MESSAGES/sphinx.po``: Sphinx's own.
INTERFACE = "sphinx"
#: The class that makes a literal block a translatable text diagram.
DIAGRAM = "diagram"
#: The words of an HTML output that a reader reads: an element's text, or an attribute's value. (A label
#: that holds its input and its words, as the player's repeat modes do, has them in a ``span``.)
_WORDS = re.compile(r"(?P<open><(?P<tag>th|caption|label|span)\b[^>]*>)(?P<text>[^<]*)(?P<close></(?P=tag)\s*>)"
                    r"""|(?P<name>\s(?:alt|title|aria-label)=)(?P<quote>["'])(?P<value>.*?)(?P=quote)""",
                    re.I | re.S)
#: Parts of an HTML output that hold no words for the reader.
_SCRIPT = re.compile(r"(<(script|style)\b.*?</\2\s*>)", re.I | re.S)


#: A number in an output's words: a parameter of its message, not part of it.
#: (Not an exponent "m^2", a denominator "pi/2", nor an equation's number "(12)".)
_NUMBER = re.compile(r"(?<![\w.^/])(?<!\()\d+(?:\.\d+)?(?:e[-+]?\d+)?(?![\w.])|(?<=\()\d+(?:\.\d+)?(?:e[-+]?\d+)?(?![\w.)])")
_PLACE = re.compile(r"\{(\d+)\}")


def _has_words(text: str) -> bool:
    return re.search(r"[^\W\d_]{2,}", text) is not None


def message_of(text: str) -> tuple[str, list[str]]:
    """An output's words as a message and its numbers: each number becomes ``{1}``, ``{2}``, ...

    The words of an output are often built from values ("rtol = atol = 1e-06", "Animation of the
    slider-crank (Case 2)"); with the numbers as parameters the message stays the same when the
    values change, and one translation serves every value.

    >>> message_of("|f| at 1000 s, rtol = 1e-06, RK45")
    ('|f| at {1} s, rtol = {2}, RK45', ['1000', '1e-06'])
    """
    numbers = []

    def place(match):
        numbers.append(match.group(0))
        return "{%d}" % len(numbers)

    return _NUMBER.sub(place, text), numbers


def localised(text: str, lookup) -> str:
    """``text`` in the edition's language: its message looked up with ``lookup(message)`` (None or the
    message itself when there is no translation), its numbers put back in their places."""
    message, numbers = message_of(text)
    translated = lookup(message)
    if not translated or translated == message:
        return text
    return _PLACE.sub(lambda match: numbers[int(match.group(1)) - 1], translated)


def _rewrite(markup: str, translate) -> str:
    """``markup`` with every word-bearing element text and attribute passed through ``translate``.

    ``translate(text)`` gets the unescaped text and returns the new text, or None to keep it.
    """
    def replace(match):
        text = html.unescape(match.group("text" if match.group("tag") else "value")).strip()
        new = translate(text)
        if new is None or new == text:
            return match.group(0)
        if match.group("tag"):
            return f'{match.group("open")}{html.escape(new, quote=False)}{match.group("close")}'
        quote = match.group("quote")
        return f'{match.group("name")}{quote}{html.escape(new)}{quote}'

    parts = _SCRIPT.split(markup)
    # split() with two groups yields [text, script, tag name, text, script, tag name, ...]
    return "".join(_WORDS.sub(replace, part) if index % 3 == 0 else part
                   for index, part in enumerate(parts) if index % 3 != 2)


def html_messages(markup: str) -> list[str]:
    """The words of an HTML output that a reader reads, as messages (:func:`message_of`), each once, in order.

    >>> html_messages('<table><thead><tr><th class="num">max |f| [m]</th><th>rtol = 1e-06</th></tr></thead>'
    ...               '</table><img alt="A &quot;flat&quot; line" src="x.png"><label for="r">Once</label>'
    ...               '<button title="Play" aria-label="Play">1</button><script>var title="no";</script>'
    ...               '<label><input type="radio" value="loop"><span>Loop</span></label>')
    ['max |f| [m]', 'rtol = {1}', 'A "flat" line', 'Once', 'Play', 'Loop']
    """
    found = []

    def collect(text):
        message, _ = message_of(text)
        if _has_words(message) and message not in found:
            found.append(message)
        return None

    _rewrite(markup, collect)
    return found


class translated_html(nodes.raw, addnodes.translatable):
    """An HTML output whose words (:func:`html_messages`) are messages of the page's catalogue.

    Written as the raw HTML it is (Sphinx's writers dispatch on the classes it derives from).
    """

    def preserve_original_messages(self) -> None:
        self.setdefault("original_messages", html_messages(self.astext()))

    def extract_original_messages(self) -> list[str]:
        return list(self.get("original_messages", ()))

    def apply_translated_message(self, original_message: str, translated_message: str) -> None:
        lookup = {original_message: translated_message}.get
        markup = _rewrite(self.astext(), lambda text: localised(text, lookup))
        self.children = [nodes.Text(markup)]
        self.rawsource = markup


#: The class MyST-NB gives the words a ``{glue:text}`` role pastes into the prose.
PASTED = "pasted-text"


def _pasted_words(node) -> bool:
    return isinstance(node, nodes.inline) and PASTED in node.get("classes", ()) \
        and _has_words(message_of(node.astext())[0])


class glued_words(nodes.inline, addnodes.translatable):
    """Words a ``{glue:text}`` role pasted into the prose ("three of the four", a method's name in a
    sentence), in the gettext build: one message of the page's catalogue, its numbers parameters
    (:func:`message_of`). A translated edition puts the translation in after Sphinx's ``Locale``
    (:class:`TranslatePastedWords`), which parses each translated paragraph again and pastes anew."""

    def preserve_original_messages(self) -> None:
        self.setdefault("original_messages", [message_of(self.astext())[0]])

    def extract_original_messages(self) -> list[str]:
        return list(self.get("original_messages", ()))

    def apply_translated_message(self, original_message: str, translated_message: str) -> None:
        pass                                     # the gettext build only reads the message


class MarkPastedWords(SphinxTransform):
    """In the gettext build: the words pasted by a ``{glue:text}`` role become :class:`glued_words`, so
    that the catalogue holds them. Before Sphinx's ``PreserveTranslatableMessages`` (priority 10)."""

    default_priority = 6

    def apply(self, **kwargs) -> None:
        if self.app.builder.name != "gettext":
            return
        for node in list(self.document.findall(_pasted_words)):
            words = glued_words(node.rawsource, "", *node.children, **node.attributes)
            words.source, words.line = node.source, node.line
            node.replace_self(words)


class TranslatePastedWords(SphinxTransform):
    """In a translated edition, after Sphinx's ``Locale`` (priority 20): the words a ``{glue:text}``
    role pasted into a paragraph, translated through the page's catalogue (numbers put back)."""

    default_priority = 25

    def apply(self, **kwargs) -> None:
        catalogue = _page_catalogue(self)
        if catalogue is None:
            return
        for node in list(self.document.findall(_pasted_words)):
            text = node.astext()
            translated = localised(text, catalogue.gettext)
            if translated != text:
                node.children = [nodes.Text(translated)]


def _in_outputs(node) -> bool:
    parent = node.parent
    while parent is not None:
        if parent.get("nb_element") == "cell_code_output":
            return True
        parent = parent.parent
    return False


class MarkTranslatableParts(SphinxTransform):
    """In every build: outputs' HTML becomes :class:`translated_html`, the rest of the outputs' text
    untranslatable (it is computed); a literal block of class ``diagram`` translatable.

    Before Sphinx's ``PreserveTranslatableMessages`` (priority 10), which asks the new nodes for
    their messages, and its ``Locale`` (20), which translates them.
    """

    default_priority = 5

    def apply(self, **kwargs) -> None:
        for node in list(self.document.findall(nodes.literal_block)):
            if DIAGRAM in node.get("classes", ()):
                node["translatable"] = True
        for node in list(self.document.findall(nodes.TextElement)):
            if isinstance(node, nodes.image) or not _in_outputs(node):
                continue
            if isinstance(node, nodes.raw) and "html" in node.get("format", "").split() \
                    and html_messages(node.astext()):
                replacement = translated_html(node.rawsource, node.astext(), **node.attributes)
                replacement.source, replacement.line = node.source, node.line
                node.replace_self(replacement)
            elif isinstance(node, LITERAL_TYPE_NODES):
                node["translatable"] = False


def _page_catalogue(transform):
    """The page's catalogue in a translated edition; None in the source language, or if it has none."""
    from sphinx.locale import init as init_locale
    from sphinx.util.i18n import docname_to_domain

    if (transform.config.language or SOURCE_LANGUAGE) == SOURCE_LANGUAGE:
        return None
    folders = [str(Path(transform.env.srcdir, folder)) for folder in transform.config.locale_dirs]
    domain = docname_to_domain(transform.env.docname, transform.config.gettext_compact)
    catalogue, found = init_locale(folders, transform.config.language, domain)
    return catalogue if found else None


class TranslateLiteralNodes(SphinxTransform):
    """In a translated edition, just before Sphinx's ``Locale``: a display equation, a text diagram or
    raw HTML of the page takes its msgstr as its text, as it stands (see the module's docstring), and
    an output's words (:class:`translated_html`) their translations."""

    default_priority = 19

    def apply(self, **kwargs) -> None:
        catalogue = _page_catalogue(self)
        if catalogue is None:
            return
        # an output's words, here rather than in Locale: Locale's first pass marks a node "translated"
        # after each message whose translation is the message itself ("alpha", "nfev"), and its second
        # pass then skips the node's other messages
        for node in self.document.findall(translated_html):
            node.preserve_original_messages()
            for message in node.extract_original_messages():
                node.apply_translated_message(message, catalogue.gettext(message))
        for node in list(self.document.findall(
                lambda n: isinstance(n, LITERAL_TYPE_NODES) and not isinstance(n, addnodes.translatable)
                and is_translatable(n))):
            message = node.rawsource or node.astext()
            translated = catalogue.gettext(message)
            if translated and translated != message:
                node.children = [nodes.Text(translated)]
                node.rawsource = translated
            node["translatable"] = False                  # Sphinx's Locale would make it "::"


class TranslateCodePrompts(SphinxPostTransform):
    """In a translated edition: MyST-NB's "Show code cell source" and its kin, after MyST-NB's
    ``HideInputCells`` (priority 199) has written them, from the interface catalogue."""

    default_priority = 200
    formats = ("html",)

    def run(self, **kwargs) -> None:
        from myst_nb.sphinx_ import HideCodeCellNode

        if (self.config.language or SOURCE_LANGUAGE) == SOURCE_LANGUAGE:
            return
        gettext = get_translation(INTERFACE)
        for node in self.document.findall(HideCodeCellNode):
            for key in ("prompt_show", "prompt_hide"):
                if node.get(key):
                    node[key] = str(gettext(node[key]))


#: The attributes whose value the theme and MyST-NB write as it is, untranslated.
_INTERFACE_ATTRIBUTE = re.compile(r"""(?P<name>\s(?:title|aria-label|placeholder|data-bs-title)=)(?P<quote>["'])"""
                                  r"(?P<value>[^\"'<>]*[^\W\d_][^\"'<>]*)(?P=quote)")


def localised_attributes(markup: str, gettext) -> str:
    """``markup`` with each value of a ``title``, ``aria-label``, ``placeholder`` or ``data-bs-title``
    that ``gettext`` translates replaced by its translation.

    >>> words = {"Toggle hidden content": "Ẩn/hiện phần bị ẩn", "Page": "Trang"}.get
    >>> localised_attributes('<summary aria-label="Toggle hidden content"><nav aria-label="Page" '
    ...                      'title="Pages">', lambda text: words(text, text))
    '<summary aria-label="Ẩn/hiện phần bị ẩn"><nav aria-label="Trang" title="Pages">'
    """
    def replace(match):
        value = html.unescape(match.group("value"))
        translated = str(gettext(value))
        if translated == value:
            return match.group(0)
        return f'{match.group("name")}{match.group("quote")}{html.escape(translated)}{match.group("quote")}'

    return _INTERFACE_ATTRIBUTE.sub(replace, markup)


def translate_interface_attributes(app) -> None:
    """In a translated edition's HTML builds: every page the templates render passes through
    :func:`localised_attributes` with the interface catalogue."""
    if (app.config.language or SOURCE_LANGUAGE) == SOURCE_LANGUAGE or app.builder.format != "html":
        return
    templates, gettext = app.builder.templates, get_translation(INTERFACE)
    render = templates.render
    templates.render = lambda template, context: localised_attributes(render(template, context), gettext)


def translate_search_script(app, exception) -> None:
    """In a translated edition's HTML builds: the messages of the search page's script that the interface
    catalogue translates, put into the ``_static/translations.js`` that Sphinx copied from its own."""
    if exception or (app.config.language or SOURCE_LANGUAGE) == SOURCE_LANGUAGE or app.builder.format != "html":
        return
    import json

    path = Path(app.outdir, "_static", "translations.js")
    if not path.exists():
        return
    text = path.read_text(encoding="utf-8").strip()
    start, end = "Documentation.addTranslations(", ");"
    if not (text.startswith(start) and text.endswith(end)):
        return
    data = json.loads(text[len(start):-len(end)])
    gettext = get_translation(INTERFACE)
    for message, translation in data["messages"].items():
        if isinstance(translation, str) and str(gettext(message)) != message:
            data["messages"][message] = str(gettext(message))
    path.write_text(f"{start}{json.dumps(data, ensure_ascii=False, indent=4)}{end}\n", encoding="utf-8")


def gettext_sees_the_html_outputs(app, config):
    """The gettext build keeps the outputs the HTML build shows (MyST-NB's own choice for it is the
    plain text), so that it extracts the words the site shows. (An override for the builder
    ``gettext`` only, set in every build so that the configuration stays the same from one to the next.)"""
    from myst_nb.core.render import base_render_priority

    html_ranks = [("gettext", mime, rank) for mime, rank in base_render_priority()["html"].items()]
    config.nb_mime_priority_overrides = [*config.nb_mime_priority_overrides,
                                         *(o for o in html_ranks if o not in config.nb_mime_priority_overrides)]


def setup(app):
    app.add_transform(MarkTranslatableParts)
    app.add_transform(MarkPastedWords)
    app.add_transform(TranslatePastedWords)
    app.add_transform(TranslateLiteralNodes)
    app.add_post_transform(TranslateCodePrompts)
    app.connect("config-inited", gettext_sees_the_html_outputs)
    app.connect("builder-inited", translate_interface_attributes)
    app.connect("build-finished", translate_search_script)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
