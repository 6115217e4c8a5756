"""The library reference (``book/reference.md``): Sphinx's autodoc, with three rules of this book.

autodoc writes each entry from the library's own docstrings (numpy style, read by napoleon). What
it does not do by itself:

- **Each object once.** A name that ``closedloop`` exports at its top is documented there, and the
  subpackage that defines it skips it (``autodoc-skip-member``): no docstring is printed twice.
- **Every reference checked, linked where it can be.** A docstring that names a part of the library
  links to its entry, under whichever public name documents it; a part the reference does not
  document (an inner module, a constant of one) is written as code once it is found to exist, and so
  is a name of Python or of a dependency. A name that exists nowhere stays a warning, and the build,
  run with warnings as errors, fails on it.
- **The docstrings in English in every edition.** Their text is the library's, as the reader's
  ``help()`` shows it: it stays out of the translation catalogues (the page's own words are
  translated as any page's). Absolute values written in plain text (``|f|``) are shown as written,
  not read as reStructuredText substitutions.
"""

from __future__ import annotations

import builtins
import importlib
import inspect
import re
import sys

from docutils import nodes
from sphinx import addnodes
from sphinx.errors import PycodeError
from sphinx.pycode import ModuleAnalyzer
from sphinx.transforms import SphinxTransform
from sphinx.util.docutils import SphinxDirective

PACKAGE = "closedloop"
#: ``|f|``: an absolute value or a norm, as the docstrings write it in plain text
ABSOLUTE = re.compile(r"(?<![\\`|])\|(?=[^\s|])([^|`]*?[^\s\\|])\|(?![`|])")
#: A role naming an object without its module: ``:func:`partition_condition```
ROLE = re.compile(r":(\w+):`([~!]?)([A-Za-z_]\w*)`")
#: The HTML class of every block of a docstring's text: English in every edition
DOCSTRING = "docstring"
_MISSING = object()


def read_docstring(app, what, name, obj, options, lines):
    """Note the module being documented (for :func:`skip_exported_above`); absolute values as written."""
    if what == "module":
        app.env.closedloop_reference_module = name
    lines[:] = [ABSOLUTE.sub(r"\\|\1\\|", line) for line in lines]


def skip_exported_above(app, what, name, obj, skip, options):
    """Skip, in a subpackage or module, a member that ``closedloop`` itself exports (documented there)."""
    module = getattr(app.env, "closedloop_reference_module", None)
    if skip or what != "module" or module in (None, PACKAGE):
        return None
    top = importlib.import_module(PACKAGE)
    if name in getattr(top, "__all__", ()) and getattr(top, name, None) is obj:
        return True
    return None


def home_comment(name, obj):
    """The ``#:`` comment of a constant where the library defines it, as lines ([] if it has none).

    A package that exports a constant imports it, without the comment, and autodoc's ``automodule``
    leaves out a constant with no comment in the module it documents: :class:`LibraryModule` names
    such a constant with ``autodata``, and the entry takes its home module's comment."""
    for module_name, module in sorted(sys.modules.items()):
        if module_name.split(".")[0] != PACKAGE or getattr(module, name, _MISSING) is not obj:
            continue
        try:
            comment = ModuleAnalyzer.for_module(module_name).find_attr_docs().get(("", name))
        except PycodeError:                       # a module with no source of its own
            continue
        if comment:                               # its unqualified names are its module's
            return [ROLE.sub(rf":\1:`~{module_name}.\3`", line) for line in comment]
    return []


def fill_constant(app, what, name, obj, options, lines):
    """A constant documented where it is exported with the ``#:`` comment of its home module."""
    if what not in ("data", "attribute"):
        return
    own = "\n".join(lines).strip()
    inherited = type(obj).__doc__
    if not own or (isinstance(inherited, str) and own == inspect.cleandoc(inherited)):  # none, or its type's
        lines[:] = home_comment(name.rsplit(".", 1)[-1], obj)


def lookup(path):
    """The object at a dotted path (the longest importable module, then its attributes), or ``_MISSING``."""
    parts = path.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attribute in parts[cut:]:
            obj = getattr(obj, attribute, _MISSING)
            if obj is _MISSING:
                return _MISSING
        return obj
    return _MISSING


def candidates(node):
    """The full paths a reference may mean: as written, in the docstring's module and class, and in
    the module where the documented object was defined."""
    target = node["reftarget"].lstrip("~.")
    module, cls = node.get("py:module"), node.get("py:class")
    names = [target]
    if module:
        names.insert(0, f"{module}.{target}")
        if cls:
            names.insert(0, f"{module}.{cls}.{target}")
    source = node.source or ""
    if "docstring of " in source:
        parts = source.rsplit("docstring of ", 1)[1].split(".")
        names += [".".join(parts[:cut] + [target]) for cut in range(len(parts), 0, -1)]
        for cut in range(len(parts), 1, -1):
            home = getattr(lookup(".".join(parts[:cut])), "__module__", None)
            if home:
                names.append(f"{home}.{target}")
    return names


def link_or_code(app, env, node, contnode):
    """``missing-reference``: a link to the entry of the same object, or the name as code if it exists."""
    if node.get("refdomain") != "py":
        return None
    if node["reftarget"] in dir(builtins):
        return contnode
    for candidate in candidates(node):
        obj = lookup(candidate)
        if obj is _MISSING:
            continue
        entry = None
        if candidate.split(".")[0] == PACKAGE and not isinstance(obj, (bool, int, float, str, tuple)):
            entry = entries_by_object(app, env).get(id(obj))
        if entry is None:
            return contnode
        uri = app.builder.get_relative_uri(node["refdoc"], entry.docname)
        return nodes.reference("", "", contnode, internal=True, refuri=f"{uri}#{entry.node_id}")
    return None


def entries_by_object(app, env):
    """The library's documented entries by the ``id`` of their object, made once per build (the
    references are resolved after every page has been read)."""
    if getattr(app, "closedloop_entries", None) is None:
        app.closedloop_entries = {}
        for name, entry in env.get_domain("py").objects.items():
            obj = lookup(name) if name.split(".")[0] == PACKAGE else _MISSING
            if obj is not _MISSING:
                app.closedloop_entries.setdefault(id(obj), entry)
    return app.closedloop_entries


def forget_entries(app, env):
    """``env-updated``: the entries of the previous build are not this one's."""
    app.closedloop_entries = None


def _from_a_docstring(node):
    if isinstance(node, addnodes.index):              # autodoc puts an entry's index just before it
        following = node.parent is not None and node.parent.index(node) + 1 < len(node.parent) \
            and node.parent[node.parent.index(node) + 1]
        return isinstance(following, addnodes.desc)
    return "docstring of " in (node.source or "") or any(
        isinstance(parent, addnodes.desc) for parent in _parents(node))


def _parents(node):
    while node.parent is not None:
        node = node.parent
        yield node


class DocstringsStayEnglish(SphinxTransform):
    """The docstrings' text out of the catalogues: not translatable, of the class :data:`DOCSTRING`
    (for the test that the rest of a translated page is translated), and in the gettext build their
    index entries left out. A heading inside a module's docstring becomes a rubric: the page's
    contents list the entries, not the docstrings' inner headings. Before Sphinx's
    ``PreserveTranslatableMessages`` (priority 10)."""

    default_priority = 5

    def apply(self, **kwargs) -> None:
        # an inline node only in the gettext build: elsewhere Sphinx takes a "translatable" inline for a
        # placeholder of its own, and moves its children to the end of its parent
        gettext = self.app.builder.name == "gettext"
        for section in list(self.document.findall(nodes.section)):
            title = section[0] if len(section) and isinstance(section[0], nodes.title) else None
            if title is not None and _from_a_docstring(title):       # a heading inside a docstring
                rubric = nodes.rubric(title.rawsource, "", *title.children, ids=section["ids"])
                rubric.source, rubric.line = title.source, title.line
                section.replace_self([rubric, *section.children[1:]])
        for node in self.document.findall(nodes.Element):
            if not _from_a_docstring(node):
                continue
            if isinstance(node, nodes.TextElement) and (gettext or not isinstance(node, nodes.inline)):
                node["translatable"] = False
                node["classes"].append(DOCSTRING)
            if isinstance(node, addnodes.index) and gettext:
                node["entries"] = []


class LibraryModule(SphinxDirective):
    """``.. library-module:: closedloop.x``: ``automodule`` with its members, and an ``autodata`` for
    each constant the module exports without documenting it itself (it imports it): autodoc's
    ``automodule`` leaves such a constant out, and :func:`fill_constant` gives it its home's comment."""

    required_arguments = 1

    def run(self):
        name = self.arguments[0]
        module = importlib.import_module(name)
        documented = ModuleAnalyzer.for_module(name).find_attr_docs()
        lines = [f".. automodule:: {name}", "   :members:", ""]
        for member in getattr(module, "__all__", ()):
            obj = getattr(module, member)
            if not (inspect.isroutine(obj) or inspect.isclass(obj) or inspect.ismodule(obj)) \
                    and ("", member) not in documented:
                lines += [f".. autodata:: {name}.{member}", ""]
        return self.parse_text_to_nodes("\n".join(lines))


def setup(app):
    app.add_directive("library-module", LibraryModule)
    app.setup_extension("sphinx.ext.autodoc")
    app.setup_extension("sphinx.ext.napoleon")
    app.add_transform(DocstringsStayEnglish)
    app.connect("autodoc-process-docstring", fill_constant)
    app.connect("autodoc-process-docstring", read_docstring)
    app.connect("autodoc-skip-member", skip_exported_above)
    app.connect("missing-reference", link_or_code)
    app.connect("env-updated", forget_entries)
    return {"parallel_read_safe": False, "parallel_write_safe": True}
