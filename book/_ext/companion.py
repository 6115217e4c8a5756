"""The book in its readers' hands: its version and citation, its code as downloads, and its course edition.

**One version.** The version is ``closedloop.__version__`` (``src/closedloop/__init__.py``): the wheel
is named with it (``pyproject.toml`` reads it), and so is the companion's archive; the pages show it
through the role below, and ``CITATION.cff`` and ``CHANGELOG.md`` carry it too (``tests/test_release.py``
checks that every one of them agrees).

**The citation.** ``CITATION.cff`` is read once; the role ``{companion}`KEY``` writes, on any page,
``version``, ``date`` (the release date), ``year``, ``authors``, ``title``, and a link to ``wheel``,
``archive`` or ``citation`` (the file ``CITATION.cff``), or to the ``repository``. Every page carries
the citation as Highwire Press ``<meta>`` tags (``citation_title``, ...), which reference managers
read, and the PDF's title page reads them too (``book/print/prepare.js``).

**The code travels with the site.** ``make book`` builds the library's wheel into ``_build/dist``
first (``pip wheel``); the HTML build copies it into ``_downloads``, with ``CITATION.cff``, and writes
the companion's archive there: every notebook the site offers (``book/_ext/ipynb_download.py``),
laid out as in the repository with the files they read (``DOWNLOAD_FILES``), the wheel, the library's
source (installable with pip) and a short ``README.md`` with :data:`RUN_COMMANDS`. Every page's
download menu (sphinx-book-theme's) offers both files, beside the page's own notebook. The directive
``{companion-commands}`` writes :data:`RUN_COMMANDS` into a page (the page "Run it yourself").

**The repository.** Its address is ``repository: url:`` in ``_config.yml`` and nowhere else: once it is
set, the theme's repository and issue buttons are turned on here, and the tag ``repository`` shows
the text in ``{only} repository`` blocks.

**The course edition.** With ``closedloop_edition = "course"`` (``make course``), the same site
without any solution: every ``{solution}`` and gated solution is removed from the pages (prose, code and
the checks' verdicts, which only solutions print), from the chapters' notebook downloads
(``exercises/make_student.py``'s :func:`without_solutions`), no page's MyST source is offered, and the
instructors-only pages (:data:`INSTRUCTORS_ONLY`, the rubrics) are left out of its table of contents.
As a script, this module writes that edition's configuration and table of contents::

    python book/_ext/companion.py course-config LANGUAGE > _build/course/LANGUAGE/_config.yml
    python book/_ext/companion.py course-toc > _build/course/_toc.yml
"""

from __future__ import annotations

import functools
import html
import posixpath
import shutil
import sys
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
#: Where ``make book`` puts the wheel before the site is built.
WHEEL_FOLDER = ROOT / "_build" / "dist"
#: The pages an instructor keeps to himself: the course edition leaves them out (and so does the PDF).
INSTRUCTORS_ONLY = ("book/rubrics",)
#: Files of the repository that the companion's archive holds as they are.
ARCHIVE_FILES = ("CITATION.cff", "CHANGELOG.md", "LICENSE", "LICENSE-TEXT", "pyproject.toml")
#: From the downloads to a running notebook: ``{wheel}`` is the wheel's file name.
RUN_COMMANDS = """\
python3 -m venv venv
venv/bin/pip install jupyterlab
venv/bin/pip install "{wheel}[plot]"
venv/bin/jupyter lab"""
#: The words the extension writes itself, by language (the pages' own words are in the catalogues).
TEXTS = {
    "en": {"wheel": "library (.whl)", "wheel_tip": "Download the library, closedloop {version}",
           "archive": "companion (.zip)",
           "archive_tip": "Download the companion {version}: every notebook, the checks, the library"},
    "vi": {"wheel": "thư viện (.whl)", "wheel_tip": "Tải thư viện closedloop {version}",
           "archive": "sách đồng hành (.zip)",
           "archive_tip": "Tải sách đồng hành {version}: mọi notebook, các phép kiểm tra, thư viện"},
}
ARCHIVE_README = """\
# {title}

Version {version} ({date}), by {authors}. The code is under the MIT licence (LICENSE), the
text and figures under CC BY 4.0 (LICENSE-TEXT); CITATION.cff says how to cite it.

This archive holds every page of the book that runs as a notebook, laid out as in its repository:

- `chapters/`: the thirteen chapters, executed, with their outputs;
- `exercises/`: the exercise notebooks, each `...` waiting for your answer, and `checking/`, the
  checks they import;
- `book/`: the notation page and the appendix on chapter 8's data, and `book/data/`, the data that
  chapters 8 and 9 read;
- `{wheel}`: the library, `closedloop`, which every notebook imports;
- `src/` and `pyproject.toml`: the library's source (`pip install ".[plot]"` here installs it too).

To run them, with Python 3.11 or later, in this folder:

    {commands}

On Windows write `venv\\Scripts\\` for `venv/bin/`. JupyterLab opens in your
browser: open any notebook and run its cells.
"""


# --- what every part reads ----------------------------------------------------------------------
def version() -> str:
    """The one version: ``closedloop.__version__``."""
    from closedloop import __version__

    return __version__


@functools.cache
def citation() -> dict:
    """``CITATION.cff`` as a dict (its ``date-released`` a ``datetime.date``)."""
    import yaml

    return yaml.safe_load((ROOT / "CITATION.cff").read_text(encoding="utf-8"))


def wheel_name(release: str | None = None) -> str:
    return f"closedloop-{release or version()}-py3-none-any.whl"


def archive_name(release: str | None = None) -> str:
    return f"closedloop-companion-{release or version()}.zip"


def authors() -> str:
    return ", ".join(person.get("name") or f"{person['given-names']} {person['family-names']}"
                     for person in citation()["authors"])


def values() -> dict:
    """Every value the role can write, as text."""
    found = citation()
    return {"version": version(), "date": found["date-released"].isoformat(),
            "year": str(found["date-released"].year), "authors": authors(), "title": found["title"],
            "wheel": wheel_name(), "archive": archive_name(), "citation": "CITATION.cff"}


def repository_url(app) -> str:
    return (app.config.html_theme_options or {}).get("repository_url", "") or ""


# --- the role and the directive -----------------------------------------------------------------
LINKED = {"wheel", "archive", "citation"}


def companion_role(name, rawtext, text, lineno, inliner, options=None, content=None):
    """``{companion}`KEY```: a value of :func:`values`, a link to a download, or to the repository."""
    from docutils import nodes

    env = inliner.document.settings.env
    key = text.strip()
    if key == "repository":                 # used inside {only} repository, which drops it while no url is set
        url = repository_url(env.app)
        return [nodes.reference(url, url, refuri=url) if url else nodes.inline("", "")], []
    known = values()
    if key not in known:
        message = inliner.reporter.error(f"{{companion}}`{key}`: unknown; one of {sorted(known)} or repository",
                                         line=lineno)
        return [inliner.problematic(rawtext, rawtext, message)], [message]
    if key in LINKED:
        uri = posixpath.relpath(f"_downloads/{known[key]}", posixpath.dirname(env.docname) or ".")
        return [nodes.reference(known[key], "", nodes.literal(known[key], known[key]), refuri=uri,
                                classes=["companion-download"])], []
    return [nodes.inline(known[key], known[key], classes=[f"companion-{key}"])], []


def commands_directive():
    from docutils import nodes
    from sphinx.util.docutils import SphinxDirective

    class Commands(SphinxDirective):
        """``{companion-commands}``: :data:`RUN_COMMANDS` with this version's wheel, as a shell block."""

        def run(self):
            text = RUN_COMMANDS.format(wheel=wheel_name())
            block = nodes.literal_block(text, text, language="bash")
            block["classes"].append("companion-commands")
            return [block]

    return Commands


# --- the course edition -------------------------------------------------------------------------
def course_transform():
    from sphinx.transforms import SphinxTransform

    class RemoveSolutions(SphinxTransform):
        """In the course edition, every solution out of the page (after sphinx-exercise has merged the
        gated ones into one node each, priority 10): its prose, its code and the code's output."""

        default_priority = 11

        def apply(self, **kwargs):
            if self.config.closedloop_edition != "course":
                return
            from sphinx_exercise.nodes import solution_node

            for node in list(self.document.findall(solution_node)):
                node.parent.remove(node)
                getattr(self.env, "sphinx_exercise_registry", {}).pop(node.get("label"), None)

    return RemoveSolutions


def course_links():
    from sphinx.transforms.post_transforms import SphinxPostTransform

    class UnlinkInstructorsPages(SphinxPostTransform):
        """In the course edition a link to an instructors-only page, which it leaves out, is its text
        alone (before Sphinx resolves references, priority 10, and would find no page)."""

        default_priority = 5

        def run(self, **kwargs):
            if self.config.closedloop_edition != "course":
                return
            from docutils import nodes
            from sphinx import addnodes
            from sphinx.util import docname_join

            for ref in list(self.document.findall(addnodes.pending_xref)):
                if ref.get("reftype") == "doc" and \
                        docname_join(ref.get("refdoc", ""), ref["reftarget"].removesuffix(".md")) in INSTRUCTORS_ONLY:
                    ref.replace_self(nodes.inline(ref.astext(), ref.astext()))

    return UnlinkInstructorsPages


def course_sources(app, pagename, templatename, context, doctree):
    """In the course edition no page's MyST source is offered (a chapter's holds its solutions)."""
    if app.config.closedloop_edition == "course":
        context["sourcename"] = ""


def course_config(language: str) -> dict:
    """The configuration of the course edition in ``language`` (``editions.edition_config`` and the flag)."""
    sys.path.insert(0, str(HERE))
    from editions import edition_config

    config = edition_config(language)
    config["sphinx"]["config"]["closedloop_edition"] = "course"
    return config


def course_toc() -> dict:
    """``_toc.yml`` without the instructors-only pages."""
    import yaml

    toc = yaml.safe_load((ROOT / "_toc.yml").read_text(encoding="utf-8"))
    for part in toc["parts"]:
        part["chapters"] = [entry for entry in part["chapters"] if entry["file"] not in INSTRUCTORS_ONLY]
    return toc


# --- the site -----------------------------------------------------------------------------------
def set_up(app, config):
    """The version for Sphinx, the repository's buttons when its address is set, the tags."""
    config.version = config.release = version()
    options = config.html_theme_options
    if options.get("repository_url"):
        options["use_repository_button"] = options["use_issues_button"] = True
        app.tags.add("repository")
    app.tags.add("course_edition" if config.closedloop_edition == "course" else "self_study_edition")


def check_wheel(app):
    if app.builder.name == "html" and not (WHEEL_FOLDER / wheel_name()).is_file():
        from sphinx.errors import ExtensionError

        raise ExtensionError(f"the wheel {WHEEL_FOLDER / wheel_name()} is missing: `make book` builds it "
                             "before the site (book/_ext/companion.py)")


def texts(app) -> dict:
    return TEXTS.get((app.config.language or "en").split("_")[0], TEXTS["en"])


def add_meta_and_menu(app, pagename, templatename, context, doctree):
    """The citation as ``<meta>`` tags; the wheel and the archive in the page's download menu."""
    known = values()
    meta = {"citation_title": known["title"], "citation_author": known["authors"],
            "citation_publication_date": known["date"].replace("-", "/"), "closedloop:version": known["version"],
            "closedloop:date": known["date"], "closedloop:wheel": known["wheel"],
            "closedloop:archive": known["archive"], "closedloop:repository": repository_url(app)}
    context["metatags"] = context.get("metatags", "") + "".join(
        f'\n<meta name="{name}" content="{html.escape(value)}">' for name, value in meta.items() if value)
    group = next((button for button in context.get("header_buttons", [])
                  if button.get("label") == "download-buttons"), None)
    if group is None:
        return
    if not context.get("sourcename"):           # no source offered: no button that leads to _sources/
        group["buttons"] = [b for b in group["buttons"] if b.get("label") != "download-source-button"]
    words, root = texts(app), context["pathto"]("_downloads", 1)
    for key, icon in (("wheel", "fas fa-box"), ("archive", "fas fa-file-zipper")):
        group["buttons"].append({"type": "link", "url": f"{root}/{known[key]}", "text": words[key],
                                 "tooltip": words[f"{key}_tip"].format(version=known["version"]),
                                 "icon": icon, "label": f"download-{key}-button"})


def write_downloads(app, exception):
    """``_downloads``: the wheel, ``CITATION.cff`` and the companion's archive (HTML builds only)."""
    if exception is not None or app.builder.name != "html":
        return
    folder = Path(app.outdir) / "_downloads"
    folder.mkdir(parents=True, exist_ok=True)
    shutil.copyfile(WHEEL_FOLDER / wheel_name(), folder / wheel_name())
    shutil.copyfile(ROOT / "CITATION.cff", folder / "CITATION.cff")
    write_archive(Path(app.outdir), folder / archive_name())


def archive_entries(outdir: Path) -> dict:
    """``{path in the archive: file}``: the site's notebooks, the files they read, the library."""
    from ipynb_download import DOWNLOAD_FILES

    import fnmatch

    entries = {}
    sources = outdir / "_sources"
    for notebook in sorted(sources.rglob("*.ipynb")):
        page = notebook.relative_to(sources).with_suffix("").as_posix()
        entries[f"{page}.ipynb"] = notebook
        for pattern, paths in DOWNLOAD_FILES.items():
            if fnmatch.fnmatch(page, pattern):
                for path in paths:
                    source = ROOT / path
                    files = sorted(source.rglob("*")) if source.is_dir() else [source]
                    for file in files:
                        if file.is_file() and "__pycache__" not in file.parts:
                            entries[file.relative_to(ROOT).as_posix()] = file
    for file in sorted((ROOT / "src").rglob("*")):
        if file.is_file() and "__pycache__" not in file.parts and ".egg-info" not in file.as_posix():
            entries[file.relative_to(ROOT).as_posix()] = file
    for name in ARCHIVE_FILES:
        entries[name] = ROOT / name
    entries[wheel_name()] = WHEEL_FOLDER / wheel_name()
    return entries


def archive_readme() -> str:
    known = values()
    return ARCHIVE_README.format(commands=RUN_COMMANDS.format(wheel=known["wheel"]).replace("\n", "\n    "),
                                 **known)


def write_archive(outdir: Path, target: Path) -> Path:
    """The companion's archive: one folder, ``closedloop-companion-<version>/``, written reproducibly
    (entries sorted, dated 1980-01-01, as a wheel's are without SOURCE_DATE_EPOCH)."""
    top = target.stem
    partial = target.with_name(target.name + ".partial")

    def add(stream, name, data):
        info = zipfile.ZipInfo(f"{top}/{name}", date_time=(1980, 1, 1, 0, 0, 0))
        info.compress_type = zipfile.ZIP_DEFLATED
        info.external_attr = 0o644 << 16
        stream.writestr(info, data)

    entries = archive_entries(outdir)
    with zipfile.ZipFile(partial, "w") as stream:
        add(stream, "README.md", archive_readme().encode("utf-8"))
        for name in sorted(entries):
            add(stream, name, entries[name].read_bytes())
    partial.replace(target)
    return target


def setup(app):
    app.add_config_value("closedloop_edition", "self-study", "env", types=[str])
    app.add_role("companion", companion_role)
    app.add_directive("companion-commands", commands_directive())
    app.add_transform(course_transform())
    app.add_post_transform(course_links())
    app.connect("config-inited", set_up)
    app.connect("builder-inited", check_wheel)
    app.connect("html-page-context", course_sources, priority=300)
    app.connect("html-page-context", add_meta_and_menu, priority=502)   # after the theme's buttons (501)
    app.connect("build-finished", write_downloads)
    return {"parallel_read_safe": True, "parallel_write_safe": True}


def main(argv):
    import yaml

    if len(argv) == 2 and argv[0] == "course-config":
        print(yaml.safe_dump(course_config(argv[1]), allow_unicode=True, sort_keys=False), end="")
    elif argv == ["course-toc"]:
        print(yaml.safe_dump(course_toc(), allow_unicode=True, sort_keys=False), end="")
    else:
        print("usage: companion.py course-config LANGUAGE | course-toc", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
