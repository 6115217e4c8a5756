"""Turn a notebook written in MyST Markdown into one that plain Jupyter shows as written.

Jupyter renders CommonMark with ``$`` math; it shows MyST's directives (```` ```{note} ````),
roles (``{doc}`...` ``), targets (``(label)=``) and comments (``% ...``) as raw text. Here
markdown-it-py, with the plugins that myst-parser itself uses, finds them in each markdown
cell, and each is replaced by plain Markdown: an admonition by a quoted block under its title
in bold, an exercise by a heading "Exercise 6.3: title", a solution by a heading "Solution", a
figure by an image (its file attached to the cell), a role by a link or its text.

What a role names (a page's title, an equation's number, a glued value, a citation) is asked
of a :class:`Resolver`; the one here knows nothing of the book and answers with the role's
own text. The Sphinx extension ``ipynb_download`` passes one that asks the built book.

Each exercise's heading ends with its expected time and difficulty (:func:`exercise_effort`, from
``exercises/effort.yml``), as on the site and in the student notebooks.

Code cells tagged ``remove-cell``, which the page does not show (they glue computed values into the
prose), are dropped: the download holds the code the reader sees, and nothing that needs the build.
Code cells lose the solution markers of the exercise notebooks (``# BEGIN SOLUTION``,
``# END SOLUTION``, ``# STUDENT: ...``), which are for ``exercises/make_student.py`` only.
"""

from __future__ import annotations

import base64
import mimetypes
import re
from pathlib import Path

__all__ = ["Resolver", "convert_markdown", "convert_notebook", "strip_markers", "MARKER", "exercise_effort"]

#: A line that only the build reads: the solution markers of the exercise notebooks.
MARKER = re.compile(r"^[ \t]*# (BEGIN SOLUTION|END SOLUTION|STUDENT:).*(\n|$)", re.M)

ADMONITIONS = {"note", "tip", "hint", "important", "warning", "caution", "attention", "danger", "error",
               "seealso", "admonition", "margin", "sidebar", "topic", "epigraph", "pull-quote", "dropdown",
               "card", "grid-item-card", "todo"}
TITLES = {"seealso": "See also", "todo": "To do"}
#: A link target that MyST reads as a label (``[(16)](eq-16)``): no scheme, no path, no extension.
LABEL_HREF = re.compile(r"^[A-Za-z][\w-]*$")
DROPPED = {"toctree", "tableofcontents", "contents", "bibliography", "solution-end", "exercise-end",
           "glossary-end", "code-cell", "raw-cell"}
CONTAINERS = {"grid", "grid-item", "tab-set", "div", "container", "only", "rst-class"}


#: Every exercise's expected time and difficulty: ``{"6.3": [minutes, "easy" | "medium" | "hard"]}``.
EFFORT_FILE = Path(__file__).resolve().parents[2] / "exercises" / "effort.yml"
#: How they are written, by language: after the exercise's title, e.g. "10 min · easy".
EFFORT_TEXTS = {"en": {"format": "{minutes} min · {level}", "easy": "easy", "medium": "medium", "hard": "hard"},
                "vi": {"format": "{minutes} phút · {level}", "easy": "dễ", "medium": "trung bình", "hard": "khó"}}


def efforts():
    """``exercises/effort.yml``: ``{number: (minutes, level)}``."""
    import yaml

    return {str(number): (int(minutes), level)
            for number, (minutes, level) in yaml.safe_load(EFFORT_FILE.read_text(encoding="utf-8")).items()}


def exercise_effort(number: str, language: str = "en") -> str:
    """The expected time and difficulty of exercise ``number`` ("6.3"), as written after its title.

    Raises
    ------
    KeyError
        If ``exercises/effort.yml`` does not list the exercise.
    """
    minutes, level = efforts()[number]
    words = EFFORT_TEXTS.get(language, EFFORT_TEXTS["en"])
    return words["format"].format(minutes=minutes, level=words[level])


def parser():
    """markdown-it-py set up as myst-parser sets it up, for the syntax a MyST notebook may hold."""
    from markdown_it import MarkdownIt
    from mdit_py_plugins.amsmath import amsmath_plugin
    from mdit_py_plugins.colon_fence import colon_fence_plugin
    from mdit_py_plugins.deflist import deflist_plugin
    from mdit_py_plugins.dollarmath import dollarmath_plugin
    from mdit_py_plugins.front_matter import front_matter_plugin
    from mdit_py_plugins.myst_blocks import myst_block_plugin
    from mdit_py_plugins.myst_role import myst_role_plugin

    return (MarkdownIt("commonmark").enable("table").use(front_matter_plugin).use(myst_block_plugin)
            .use(myst_role_plugin).use(colon_fence_plugin).use(dollarmath_plugin).use(amsmath_plugin)
            .use(deflist_plugin))


class Resolver:
    """What a role or a directive refers to; this one knows no book and keeps the role's text.

    Subclasses answer from a build. Each method returns Markdown.
    """

    def __init__(self, docname: str = "", srcdir: Path | None = None):
        self.docname, self.srcdir = docname, srcdir

    @staticmethod
    def split_target(content):
        """``"text <target>"`` -> ("text", "target"); ``"target"`` -> (None, "target")."""
        match = re.match(r"^(.*?)\s*<([^<>]+)>\s*$", content, flags=re.S)
        return (match.group(1), match.group(2)) if match else (None, content.strip())

    def role(self, name, content):
        text, target = self.split_target(content)
        if name == "math":
            return f"${content}$"
        if name in ("code", "literal", "samp", "file", "command", "program", "envvar"):
            return f"`{content}`"
        if name in ("sub", "sup", "kbd"):
            return f"<{name}>{content}</{name}>"
        if name == "abbr":
            return re.sub(r"\s*\(.*\)\s*$", "", content)
        if name.startswith("cite"):
            return self.cite([key.strip() for key in content.split(",")], name)
        if name == "doc":
            return self.doc(target, text)
        if name in ("ref", "prf:ref", "numref", "eq", "term", "any"):
            return self.ref(name, target, text)
        if name in ("glue", "glue:", "glue:any", "glue:text", "glue:md", "glue:math"):
            key, _, spec = content.partition(":")
            return self.glue(name, key.strip(), spec.strip())
        return text if text is not None else target

    # each of these is given the role's pieces and returns Markdown
    def doc(self, target, text):
        """The page's title (its first heading, when the source is at hand); no link."""
        if text:
            return text
        if self.srcdir is not None:
            page = (Path(self.srcdir) / self.docname).parent / target
            source = page.with_name(page.name + ".md")
            if source.is_file():
                heading = re.search(r"^# (.+)$", source.read_text(encoding="utf-8"), flags=re.M)
                if heading:
                    return heading.group(1).strip()
        return target.rsplit("/", 1)[-1]

    def ref(self, kind, target, text):
        if kind == "eq":
            return text or f"({target})"
        return text or target

    def cite(self, keys, style):
        return "(" + "; ".join(keys) + ")"

    def label_url(self, label):
        """Where a Markdown link to a bare label, ``[(16)](eq-16)``, should go: a URL, or None for none."""
        return None

    def glue(self, kind, key, spec):
        return f"`{key}`"

    def image(self, path):
        """The file of an image or figure, relative to the page: (bytes, mime type), or None."""
        if self.srcdir is None:
            return None
        file = (Path(self.srcdir) / self.docname).parent / path
        if path.startswith("/"):
            file = Path(self.srcdir) / path.lstrip("/")
        return (file.read_bytes(), mimetypes.guess_type(file.name)[0] or "image/png") if file.is_file() else None

    def glued_image(self, key):
        """The (bytes, mime type) of a glued figure, or None."""
        return None


def _options(body):
    """A directive's body split into its options (``:key: value`` lines or a YAML block) and its content."""
    lines = body.splitlines()
    options = {}
    if lines and lines[0].strip() == "---":
        import yaml

        end = next((i for i in range(1, len(lines)) if lines[i].strip() == "---"), None)
        if end is not None:
            options = yaml.safe_load("\n".join(lines[1:end])) or {}
            lines = lines[end + 1:]
    else:
        while lines and (match := re.match(r"^:([\w-]+):\s*(.*)$", lines[0])):
            options[match.group(1)] = match.group(2).strip()
            lines = lines[1:]
    while lines and not lines[0].strip():
        lines = lines[1:]
    return options, "\n".join(lines).rstrip()


def _quote(text):
    return "\n".join(("> " + line).rstrip() for line in text.splitlines())


class Converter:
    """One page's conversion: keeps the resolver and the images to attach to the current cell."""

    def __init__(self, resolver: Resolver | None = None):
        self.resolver = resolver or Resolver()
        self.md = parser()
        self.attachments = {}

    # --- images -------------------------------------------------------------------------
    def attach(self, found, name_hint):
        if not found:
            return None
        data, mime = found
        name = f"{len(self.attachments) + 1}-{Path(name_hint).name}"
        if not Path(name).suffix:
            name += mimetypes.guess_extension(mime) or ""
        self.attachments[name] = {mime: base64.b64encode(data).decode("ascii")}
        return f"attachment:{name}"

    def image_markdown(self, url, alt, width=None):
        return f"![{alt}]({url})" if url else (f"*[{alt}]*" if alt else "")

    # --- directives ---------------------------------------------------------------------
    def directive(self, name, argument, body):
        options, content = _options(body)
        inner = self.convert(content) if content else ""
        if name in DROPPED:
            return ""
        if name in ("exercise", "exercise-start"):
            title = argument.strip()
            number = re.match(r"(\d+(?:\.\d+)*):", title)
            heading = f"Exercise {title} · {exercise_effort(number.group(1))}" if number else \
                ("Exercise: " + title if title else "Exercise")
            return f"### {heading}\n\n{inner}".rstrip()
        if name in ("solution", "solution-start"):
            return f"#### Solution\n\n{inner}".rstrip()
        if name in ("figure", "image"):
            alt = str(options.get("alt", "")) or (content.splitlines()[0] if content else "")
            url = self.attach(self.resolver.image(argument.strip()), argument.strip()) or argument.strip()
            picture = self.image_markdown(url, alt)
            return picture + (f"\n\n*{inner}*" if name == "figure" and inner else "")
        if name in ("glue:figure", "glue", "glue:any"):
            key = argument.strip()
            url = self.attach(self.resolver.glued_image(key), key)
            picture = self.image_markdown(url, str(options.get("alt", "")) or key) if url else \
                self.resolver.glue("glue:text", key, "")
            return picture + (f"\n\n*{inner}*" if inner else "")
        if name == "glue:math":
            return "$$\n" + self.resolver.glue("glue:text", argument.strip(), "") + "\n$$"
        if name == "glue:md":
            return self.resolver.glue("glue:md", argument.strip(), "")
        if name == "math":
            return f"$$\n{content}\n$$"
        if name in ("code-block", "code", "sourcecode", "literalinclude"):
            return f"```{argument.strip()}\n{content}\n```"
        if name == "raw":
            return content if "html" in argument else ""
        if name == "list-table":
            return self.list_table(argument, options, content)
        if name == "table":
            return (f"**{argument.strip()}**\n\n" if argument.strip() else "") + inner
        if name == "glossary":
            return self.glossary(content)
        if name.startswith("prf:"):
            kind = name[4:].replace("-", " ").capitalize()
            title = f"**{kind}" + (f" ({self.convert(argument.strip())})" if argument.strip() else "") + ".**"
            return f"{title}\n\n{inner}".rstrip() if kind != "Proof" else f"*Proof.* {inner}".rstrip()
        if name in CONTAINERS or name == "tab-item":
            title = f"**{self.convert(argument.strip())}**\n\n" if argument.strip() else ""
            return (title + inner).rstrip()
        # an admonition (ADMONITIONS), and any other directive: its title in bold, its body quoted
        title = self.convert(argument.strip()) if argument.strip() else \
            TITLES.get(name, name.split(":")[-1].replace("-", " ").capitalize())
        return _quote(f"**{title}**\n\n{inner}".rstrip())

    def list_table(self, argument, options, content):
        rows, row = [], None
        for line in content.splitlines():
            if re.match(r"^\*\s+-\s", line) or re.match(r"^\*\s*$", line):
                row = []
                rows.append(row)
                line = line[1:].lstrip()
            if row is None:
                continue
            if re.match(r"^\s*-\s", line):
                row.append(line.strip()[1:].strip())
            elif line.strip() and row:
                row[-1] += " " + line.strip()
        if not rows:
            return ""
        width = max(len(r) for r in rows)
        rows = [[self.convert(cell).replace("\n", " ").replace("|", "\\|") for cell in r] + [""] * (width - len(r))
                for r in rows]
        header_rows = int(options.get("header-rows", 0) or 0)
        header = rows[0] if header_rows else [""] * width
        body = rows[1:] if header_rows else rows
        lines = ["| " + " | ".join(header) + " |", "|" + "---|" * width] + ["| " + " | ".join(r) + " |" for r in body]
        return (f"**{self.convert(argument.strip())}**\n\n" if argument.strip() else "") + "\n".join(lines)

    def glossary(self, content):
        """Each term in bold on its own line, its definition below it."""
        out = []
        for line in content.splitlines():
            if line.strip() and not line[0].isspace():
                out.append(f"**{line.strip()}**  ")
            else:
                out.append(line.strip())
        return self.convert("\n".join(out)).strip()

    # --- the text ------------------------------------------------------------------------
    def convert(self, text: str) -> str:
        """``text`` (MyST Markdown) as plain Markdown."""
        lines = text.splitlines(keepends=True)
        tokens = self.md.parse(text)
        blocks, roles = [], []             # (first line, end line, replacement); (first line, end line, [(name, content)])
        handled_until = -1
        for token in tokens:
            if token.map is None:
                continue
            start, end = token.map
            if token.type in ("fence", "colon_fence") and token.info.strip().startswith("{"):
                if start < handled_until:
                    continue
                match = re.match(r"^\{([^}]+)\}\s*(.*)$", token.info.strip(), flags=re.S)
                name, argument = match.group(1), match.group(2)
                indent = re.match(r"^[ \t]*", lines[start]).group(0)
                replacement = self.directive(name, argument, token.content)
                blocks.append((start, end, "\n".join(indent + line if line else line
                                                     for line in replacement.splitlines())))
                handled_until = end
            elif token.type in ("myst_target", "myst_line_comment", "myst_block_break"):
                blocks.append((start, end, None))
            elif token.type == "math_block_label":
                blocks.append((start, end, f"$$\n{token.content.strip()}\n$$"))
            elif token.type == "inline" and token.children:
                found = [(c.meta["name"], c.content) for c in token.children if c.type == "myst_role"]
                found += [("", c.attrs["href"]) for c in token.children if c.type == "link_open"
                          and LABEL_HREF.match(str(c.attrs.get("href", "")))]
                if found and start >= handled_until:
                    roles.append((start, end, found))
        out, i = [], 0
        edits = sorted([(s, e, "block", r) for s, e, r in blocks] + [(s, e, "roles", r) for s, e, r in roles])
        for start, end, kind, payload in edits:
            if start < i:
                continue
            out += lines[i:start]
            if kind == "block":
                if payload is not None:
                    out.append(payload.rstrip("\n") + "\n")
                    if end < len(lines) and lines[end].strip():
                        out.append("\n")
            else:
                out.append(self.replace_roles("".join(lines[start:end]), payload))
            i = end
        out += lines[i:]
        return "".join(out)

    def replace_roles(self, text, found):
        """``text`` with each role of ``found`` (in order) replaced by what the resolver makes of it."""
        for name, href in [f for f in found if not f[0]]:    # links to a label: to its page, or plain text
            url = self.resolver.label_url(href)
            text = re.sub(r"\[((?:[^\[\]]|\[[^\]]*\])*)\]\(" + re.escape(href) + r"\)",
                          lambda m: f"[{m.group(1)}]({url})" if url else m.group(1), text)
        found = [f for f in found if f[0]]
        cursor, pieces = 0, []
        for name, content in found:
            words = [re.escape(w) for w in content.split()]
            pattern = re.compile(r"\{" + re.escape(name) + r"\}(`+)\s*" + r"\s+".join(words) + r"\s*\1(?!`)")
            match = pattern.search(text, cursor)
            if match is None:
                continue
            pieces += [text[cursor:match.start()], self.resolver.role(name, content)]
            cursor = match.end()
        return "".join(pieces) + text[cursor:]


def convert_markdown(text: str, resolver: Resolver | None = None) -> str:
    """A markdown cell's MyST source as plain Markdown (images are left as links to their files)."""
    return Converter(resolver).convert(text)


def strip_markers(source: str) -> str:
    """A code cell's source without the solution markers (their lines removed)."""
    return MARKER.sub("", source)


def convert_notebook(notebook, resolver: Resolver | None = None):
    """``notebook`` (nbformat, changed in place and returned) with plain Markdown and no markers."""
    converter = Converter(resolver)
    # a cell the page leaves out (the values it glues into the prose) is left out of the download too
    notebook.cells = [c for c in notebook.cells if "remove-cell" not in c.get("metadata", {}).get("tags", [])]
    for cell in notebook.cells:
        if cell.cell_type == "markdown":
            converter.attachments = {}
            cell.source = converter.convert(cell.source).strip("\n")
            if converter.attachments:
                cell["attachments"] = converter.attachments
        elif cell.cell_type == "code":
            cell.source = strip_markers(cell.source)
    notebook.cells = [c for c in notebook.cells if c.cell_type != "markdown" or c.source.strip()]
    return notebook
