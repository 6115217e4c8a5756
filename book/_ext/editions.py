"""The book's editions: English (the sources) and its translations, built from the same sources.

The English edition is ``_build/html``; each translation is built from the same sources and the same
execution cache, with Sphinx's gettext catalogues in ``locales/<language>/LC_MESSAGES`` (one ``.po``
file per page, kept in step with the sources by ``sphinx-intl``), into ``_build/html/<language>``.

As a Sphinx extension, this module puts a visible link to the same page in the other edition at the
top of every page, and sets the tag ``language_<language>`` for text meant for one edition only. As a script, it writes the configuration of a translated edition::

    python book/_ext/editions.py config vi > _build/vi/_config.yml

which is ``_config.yml`` with the edition's language and title, and the execution cache of the English
build (an absolute path, so that no notebook is executed a second time). ``config en`` is the English
configuration with those absolute paths, for the gettext build of ``make translations``.

To add a language: ``sphinx-intl update -p _build/gettext-build/_build/gettext -l XX -d locales`` (after ``make translations``
has written the templates), translate the new ``.po`` files, add ``XX`` to :data:`EDITIONS` below and to
``LANGUAGES`` in the Makefile.
"""

from __future__ import annotations

import html
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

#: Every edition: its title, and the words of the link that leads a reader to it from the other edition.
EDITIONS = {
    "en": {"title": "Closed-loop multibody dynamics: the slider-crank and its initial conditions",
           "link": "Read this page in English", "name": "English"},
    "vi": {"title": "Động lực học hệ nhiều vật có cấu trúc mạch vòng: "
                    "cơ cấu tay quay - con trượt và điều kiện đầu",
           "link": "Đọc trang này bằng tiếng Việt", "name": "Tiếng Việt",
           # the site's footer (html.extra_footer of _config.yml), which is configuration, not a page
           "footer": '<p>Mã nguồn theo <a href="https://opensource.org/license/mit">giấy phép MIT</a>; '
                     'văn bản và hình vẽ theo <a href="https://creativecommons.org/licenses/by/4.0/">giấy phép '
                     'Creative Commons Ghi công 4.0 Quốc tế (CC BY 4.0)</a>. Xem các tệp <code>LICENSE</code> và '
                     '<code>LICENSE-TEXT</code> của kho mã, và trang Giấy phép ở phần cuối sách.</p>'},
}
# (The words of the site around the pages, the theme's and the code cells' buttons, are in the edition's
# interface catalogue, locales/<language>/LC_MESSAGES/sphinx.po; see translatable.py.)
SOURCE_LANGUAGE = "en"


def edition_folder(language: str) -> str:
    """Where an edition lives inside ``_build/html``: ``""`` for English, ``"vi/"`` for Vietnamese."""
    return "" if language == SOURCE_LANGUAGE else f"{language}/"


def twin_url(pagename: str, language: str, other: str) -> str:
    """The relative URL, from page ``pagename`` of edition ``language``, of the same page in ``other``.

    >>> twin_url("chapters/06-four-cases", "en", "vi")
    '../vi/chapters/06-four-cases.html'
    >>> twin_url("chapters/06-four-cases", "vi", "en")
    '../../chapters/06-four-cases.html'
    """
    up = "../" * (pagename.count("/") + edition_folder(language).count("/"))
    return f"{up}{edition_folder(other)}{pagename}.html"


def add_edition_link(app, pagename, templatename, context, doctree):
    """Prepend the link to the other edition(s) to the page's body (pages with a body only)."""
    language = app.config.language or SOURCE_LANGUAGE
    if doctree is None or "body" not in context or language not in EDITIONS:
        return
    links = " · ".join(
        f'<a class="edition-link" href="{html.escape(twin_url(pagename, language, other))}" '
        f'hreflang="{other}" lang="{other}">{html.escape(EDITIONS[other]["link"])}</a>'
        for other in EDITIONS if other != language)
    context["body"] = f'<p class="edition-links">{links}</p>\n' + context["body"]


def edition_config(language: str, root: Path = ROOT) -> dict:
    """``_config.yml`` for a build of the edition in ``language`` run from another folder.

    The translated editions, and the gettext build that writes the templates, are built with
    ``--path-output`` so that their doctrees never mix with the English site's. Jupyter Book reads
    the configuration's paths relative to the configuration file, so the execution cache and the
    local extensions are given as absolute paths: every build uses the one execution cache.
    """
    import yaml

    if language not in EDITIONS:
        raise ValueError(f"language must be one of {sorted(EDITIONS)}, got {language!r}")
    config = yaml.safe_load((root / "_config.yml").read_text(encoding="utf-8"))
    config["execute"]["cache"] = str((root / config["execute"]["cache"]).resolve())
    config["sphinx"]["local_extensions"] = {name: str((root / folder).resolve())
                                            for name, folder in config["sphinx"]["local_extensions"].items()}
    if language != SOURCE_LANGUAGE:
        config["title"] = EDITIONS[language]["title"]
        config["html"]["extra_footer"] = EDITIONS[language]["footer"]
        config["sphinx"]["config"]["language"] = language
    return config


def tag_language(app, config):
    """The tag ``language_<language>`` (``language_en``, ``language_vi``), for text that only one
    edition shows: ``{only} language_vi``."""
    app.tags.add(f"language_{config.language or SOURCE_LANGUAGE}")


def glue_while_translating():
    """Let a translated message use the page's glued values.

    Sphinx parses each translated message as a small document of its own (``publish_msgstr``), which
    has none of the notebook's glue data, so myst-nb's ``{glue}`` roles in it fail ("No key ... found
    in glue data for this document"). The page's own English text, parsed first, names the same
    glued values (the catalogue check keeps every role of a message in its translation), so myst-nb's
    lookup here remembers the page's notebook on the parser settings, which Sphinx hands on to the
    small document, and falls back to it there.
    """
    from myst_nb.ext.glue import directives, roles, utils

    original = utils.retrieve_glue_data
    if getattr(original, "falls_back_to_the_page", False):
        return

    def retrieve_glue_data(document, key):
        if "nb_renderer" in document:
            document.settings.translated_page_notebook = document["nb_renderer"]
            return original(document, key)
        renderer = getattr(document.settings, "translated_page_notebook", None)
        if renderer is None:
            return original(document, key)
        document["nb_renderer"] = renderer                # lent for the lookup only: pages are pickled
        try:
            return original(document, key)
        finally:
            del document["nb_renderer"]

    retrieve_glue_data.falls_back_to_the_page = True
    for module in (utils, roles, directives):
        module.retrieve_glue_data = retrieve_glue_data


def translated_toctree_captions():
    """A transform: the captions of the table of contents ("Chapters", ...) in the edition's language.

    sphinx-external-toc inserts the toctrees from ``_toc.yml`` (priority 100) after Sphinx's Locale
    transform has translated the page (priority 20), so their captions, which the gettext build does
    extract, would stay English. This runs just after and looks them up in the page's catalogue.
    """
    from sphinx import addnodes
    from sphinx.locale import init as init_locale
    from sphinx.transforms import SphinxTransform
    from sphinx.util.i18n import docname_to_domain

    class TranslateToctreeCaptions(SphinxTransform):
        default_priority = 101

        def apply(self, **kwargs):
            if not self.config.language or self.config.language == SOURCE_LANGUAGE:
                return
            toctrees = [node for node in self.document.findall(addnodes.toctree) if node.get("caption")]
            if not toctrees:
                return
            folders = [str(Path(self.env.srcdir, folder)) for folder in self.config.locale_dirs]
            domain = docname_to_domain(self.env.docname, self.config.gettext_compact)
            catalog, found = init_locale(folders, self.config.language, domain)
            if found:
                for node in toctrees:
                    node["caption"] = catalog.gettext(node["caption"])

    return TranslateToctreeCaptions


def forget_the_notebook(app, doctree):
    """The page is read: drop the notebook kept on its settings (it cannot be pickled with the page)."""
    if hasattr(doctree.settings, "translated_page_notebook"):
        del doctree.settings.translated_page_notebook


def setup(app):
    glue_while_translating()
    app.add_transform(translated_toctree_captions())
    app.connect("doctree-read", forget_the_notebook)
    app.connect("config-inited", tag_language)
    app.connect("html-page-context", add_edition_link)
    return {"parallel_read_safe": True, "parallel_write_safe": True}


if __name__ == "__main__":
    import yaml

    if len(sys.argv) != 3 or sys.argv[1] != "config":
        sys.exit("usage: python book/_ext/editions.py config LANGUAGE")
    sys.stdout.write(yaml.safe_dump(edition_config(sys.argv[2]), allow_unicode=True, sort_keys=False))
