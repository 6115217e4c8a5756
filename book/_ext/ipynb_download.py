"""Offer each notebook page as a plain Jupyter notebook in the page's download menu.

sphinx-book-theme adds that entry only when a launch service (Binder, Colab,
Thebe, ...) is configured, and all of them need the network. This does the part
that needs none: put a notebook into ``_sources`` and tell the theme where it is,
as the theme's own launch code does.

- A chapter (any notebook page) is its executed notebook. MyST-NB writes it to
  ``jupyter_execute``, but when the outputs come from the execution cache (myst-nb 1.4)
  it writes it *without* them, so the outputs are merged back from the cache here.
- An exercise page (``STUDENT_PAGES``) is its student version, made by
  ``exercises/make_student.py`` from the page's source: no solution, a ``...`` where an
  answer goes, the checks kept. It is not executed: its first check stops at its ``...``.
  Its MyST source, which holds the solutions, is neither copied to ``_sources`` nor offered.

Either way its markdown is plain Markdown (``plain_notebook``): every MyST directive and
role is turned into what Jupyter renders, and what a role names (a page's title, an
equation's number, a glued value, a citation) is taken from this build. A first cell says
what the notebook needs to run, with links to the files it needs
(``DOWNLOAD_FILES``), which are shipped beside it in ``_sources``.
"""

from __future__ import annotations

import fnmatch
import importlib.util
import posixpath
import shutil
import zipfile
from contextlib import suppress
from pathlib import Path

from plain_notebook import Resolver, convert_notebook

#: Pages whose download is the student version (fnmatch patterns of docnames).
STUDENT_PAGES = ["exercises/[0-9][0-9]-*"]
#: Files (or folders, shipped zipped) that a page's notebook needs beside it: pattern -> paths
#: relative to the source folder; they go beside the notebook under the same path.
#: A path inside the page's own folder keeps its path relative to that folder (``exercises/checking`` beside
#: an exercise page is ``checking``, ``book/data/benchmark.json`` beside a page of ``book/`` is ``data/...``);
#: any other keeps its whole path (``book/data/...`` beside a chapter), so that the page's code finds it
#: where it finds it in the repository. The companion's archive holds each at its path in the repository.
DOWNLOAD_FILES = {
    "exercises/[0-9][0-9]-*": ["exercises/checking"],
    "chapters/08-error-vs-runtime": ["book/data/benchmark.json"],
    "chapters/09-stiffness-and-long-runs": ["book/data/long_runs.json"],
    "book/appendix-provenance": ["book/data/benchmark.json"],
}
RUN_NOTE = ("> **To run this notebook** you need Python 3.11 or later with the book's library, `closedloop`, "
            "and its `plot` extra: `pip install \"{wheel}[plot]\"`, with the wheel {wheel} from the book's "
            "site, whose page *Run it yourself* says more.")


class BookResolver(Resolver):
    """Resolves roles against the built book: titles, numbers, glued values, citations."""

    def __init__(self, app, docname, notebook):
        super().__init__(docname, Path(app.srcdir))
        self.app, self.env = app, app.env
        self.glued = {}
        for cell in notebook.cells:
            for output in cell.get("outputs", []):
                key = output.get("metadata", {}).get("scrapbook", {}).get("name")
                if key:
                    self.glued[key] = {mime.replace("application/papermill.record/", ""): value
                                       for mime, value in output.get("data", {}).items()}
        self._bibliography = None

    def docname_of(self, target):
        target = target.removesuffix(".md").removesuffix(".ipynb")
        if target.startswith("/"):
            return target.lstrip("/")
        return posixpath.normpath(posixpath.join(posixpath.dirname(self.docname), target))

    def url(self, docname, anchor=""):
        """A link to ``docname``: the page on the published site, or the page's notebook beside this one."""
        base = self.app.config.html_baseurl
        if base:
            return f"{base.rstrip('/')}/{docname}.html" + (f"#{anchor}" if anchor else "")
        if (Path(self.app.outdir).parent / "jupyter_execute" / f"{docname}.ipynb").exists() or \
                any(fnmatch.fnmatch(docname, p) for p in STUDENT_PAGES):
            return posixpath.relpath(docname, posixpath.dirname(self.docname) or ".") + ".ipynb"
        return None

    def link(self, text, docname, anchor=""):
        url = self.url(docname, anchor)
        return f"[{text}]({url})" if url else text

    def title(self, docname):
        title = self.env.titles.get(docname)
        return title.astext() if title is not None else docname

    def doc(self, target, text):
        docname = self.docname_of(target)
        return self.link(text or self.title(docname), docname)

    def number(self, docname, ids):
        for figtype, numbers in self.env.toc_fignumbers.get(docname, {}).items():
            for node_id in ids:
                if node_id in numbers:
                    return figtype, ".".join(map(str, numbers[node_id]))
        return None, None

    def ref(self, kind, target, text):
        std = self.env.domaindata["std"]
        if kind == "eq":
            found = self.env.domaindata.get("math", {}).get("objects", {}).get(target)
            number = f"({found[1]})" if found and found[1] else f"({target})"
            return self.link(text or number, found[0], f"equation-{target}") if found else (text or number)
        if kind == "term":
            return text or target
        if kind == "prf:ref" and target in getattr(self.env, "proof_list", {}):
            entry = self.env.proof_list[target]
            _, number = self.number(entry["docname"], entry["ids"])
            label = entry["realtype"].capitalize() + (f" {number}" if number else "")
            return self.link(text or label, entry["docname"], entry["ids"][0] if entry["ids"] else "")
        registry = getattr(self.env, "sphinx_exercise_registry", {})
        if target in registry and not text:
            node = registry[target]["node"]
            subtitle = node.children[0].children[1].astext() if len(node.children[0].children) > 1 else ""
            return self.link(f"Exercise {subtitle}".strip(), registry[target]["docname"], target)
        if target in std["labels"]:
            docname, label_id, section = std["labels"][target]
            if kind == "numref":
                figtype, number = self.number(docname, [label_id])
                if number:
                    template = text or self.app.config.numfig_format.get(figtype, "%s")
                    section = template.replace("{number}", number).replace("%s", number) \
                        .replace("{name}", section or "")
                    text = None
            return self.link(text or section or target, docname, label_id)
        if target in std["anonlabels"]:
            docname, label_id = std["anonlabels"][target]
            return self.link(text or target, docname, label_id)
        return text or target

    def label_url(self, label):
        std = self.env.domaindata["std"]
        found = self.env.domaindata.get("math", {}).get("objects", {}).get(label) or \
            std["labels"].get(label) or std["anonlabels"].get(label)
        if not found or found[0] == self.docname:
            return None
        return self.url(found[0])

    def cite(self, keys, style):
        names = []
        for key in keys:
            entry = self.bibliography().get(key)
            if entry is None:
                names.append((key, ""))
                continue
            people = entry.persons.get("author") or entry.persons.get("editor") or []
            last = [" ".join(p.last_names) for p in people]
            who = last[0] if len(last) == 1 else " and ".join(last) if len(last) == 2 else f"{last[0]} et al."
            names.append((who.replace("{", "").replace("}", ""), entry.fields.get("year", "")))
        if style in ("cite:t", "cite:ts", "cite:ct", "cite:cts"):
            text = "; ".join(f"{who} ({year})" for who, year in names)
        else:
            text = "(" + "; ".join(f"{who}, {year}" if year else who for who, year in names) + ")"
        bibliography = next((d for d in self.env.found_docs if d.endswith("bibliography")), None)
        return text if bibliography is None or self.url(bibliography) is None else \
            f"[{text}]({self.url(bibliography)})"

    def bibliography(self):
        if self._bibliography is None:
            from pybtex.database import parse_file

            self._bibliography = {}
            for name in self.app.config.bibtex_bibfiles:
                self._bibliography.update(parse_file(Path(self.app.srcdir) / name).entries)
        return self._bibliography

    def glue(self, kind, key, spec):
        data = self.glued.get(key)
        if data is None:
            return f"`{key}`"
        if kind == "glue:md" and "text/markdown" in data:
            return data["text/markdown"]
        if kind == "glue:math" and "text/latex" in data:
            return data["text/latex"].strip("$")
        from myst_nb.core.variables import format_plain_text

        return format_plain_text(data.get("text/plain", ""), spec)

    def glued_image(self, key):
        import base64

        data = self.glued.get(key, {})
        for mime in ("image/png", "image/jpeg", "image/svg+xml"):
            if mime in data:
                raw = data[mime]
                return (raw.encode() if mime == "image/svg+xml" else base64.b64decode(raw)), mime
        return None


def make_student(app):
    """The module exercises/make_student.py, which knows how solutions are marked."""
    script = Path(app.srcdir) / "exercises" / "make_student.py"
    spec = importlib.util.spec_from_file_location("make_student", script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def student_notebook(app, docname):
    """The student version of an exercise page, from its source, by exercises/make_student.py."""
    import jupytext

    return jupytext.reads(make_student(app).student_markdown(Path(app.env.doc2path(docname)).read_text()),
                          fmt="md:myst")


def executed_notebook(app, pagename):
    import nbformat

    executed = Path(app.outdir).parent / "jupyter_execute" / f"{pagename}.ipynb"
    if not executed.exists():
        return None
    notebook = nbformat.read(executed, as_version=4)
    if app.env.mystnb_config.execution_mode == "cache":
        from jupyter_cache import get_cache

        with suppress(KeyError):
            _, notebook = get_cache(app.env.mystnb_config.execution_cache_path).merge_match_into_notebook(notebook)
    return notebook


def ship(app, pagename, paths):
    """Copy ``paths`` beside the page's notebook in ``_sources`` (a folder as a .zip); return the links."""
    folder = Path(app.outdir) / "_sources" / posixpath.dirname(pagename)
    links = []
    for path in paths:
        source = Path(app.srcdir) / path
        here = posixpath.dirname(pagename)
        name = posixpath.relpath(path, here) if path.startswith(here + "/") else path
        target = folder / name
        target.parent.mkdir(parents=True, exist_ok=True)
        if source.is_dir():
            archive = target.parent / f"{target.name}.zip"
            if not archive.exists():
                with zipfile.ZipFile(archive, "w", zipfile.ZIP_DEFLATED) as stream:
                    for file in sorted(source.rglob("*")):
                        if file.is_file() and "__pycache__" not in file.parts:
                            stream.write(file, file.relative_to(source.parent).as_posix())
            links.append((f"{name}.zip", f"`{name}/` (unzip [{name}.zip]({name}.zip) here)"))
        else:
            shutil.copyfile(source, target)
            links.append((name, f"[{name}]({name})"))
    return links


def add_ipynb_source(app, pagename, templatename, context, doctree):
    import nbformat

    if doctree is None:
        return
    student = any(fnmatch.fnmatch(pagename, pattern) for pattern in STUDENT_PAGES)
    notebook = executed_notebook(app, pagename)
    if notebook is None:
        return
    resolver = BookResolver(app, pagename, notebook)
    if student:
        notebook = student_notebook(app, pagename)
        context["sourcename"] = ""       # nor is its MyST source, solutions and all, copied and offered
    elif getattr(app.config, "closedloop_edition", "") == "course":
        make_student(app).without_solutions(notebook)     # the course edition's: no solution at all
    convert_notebook(notebook, resolver)
    needs = [path for pattern, paths in DOWNLOAD_FILES.items() if fnmatch.fnmatch(pagename, pattern)
             for path in paths]
    from companion import wheel_name

    note = RUN_NOTE.format(wheel=wheel_name())
    if needs:
        note += " It also needs, beside it in the same folder: " + \
            ", ".join(text for _, text in ship(app, pagename, needs)) + "."
    notebook.cells.insert(0, nbformat.v4.new_markdown_cell(note))
    target = Path(app.outdir) / "_sources" / f"{pagename}.ipynb"
    target.parent.mkdir(parents=True, exist_ok=True)
    nbformat.write(notebook, target)
    context["ipynb_source"] = f"{pagename}.ipynb"


def setup(app):
    app.setup_extension("solution_markers")
    app.setup_extension("exercise_titles")
    # before sphinx-book-theme builds its header buttons (default priority 500)
    app.connect("html-page-context", add_ipynb_source, priority=400)
    return {"parallel_read_safe": True, "parallel_write_safe": True}
