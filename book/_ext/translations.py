"""Checks of the book's translations (``locales/<language>/LC_MESSAGES/**/*.po``), one page per file.

Used by ``tests/test_translations.py`` and by translators::

    python book/_ext/translations.py check locales/vi/LC_MESSAGES/chapters/06-four-cases.po ...

A message is right when

- it is translated: its ``msgstr`` is not empty and not fuzzy;
- it keeps the source's markup: the same inline code, math, citations, glued values, cross-reference
  targets, link targets and parameters ``{1}`` of an output's words, as many times each (display texts of references are translated; their
  targets are not); a display equation stays the same equation, only the words of its ``\text{}``
  may be translated;
- it uses the glossary's terms: where the English text names a term of ``book/glossary.md`` (the
  bold English words of each entry), the translation holds that entry's Vietnamese form. The glossary
  is the single list of terms, so one term never gets two translations. (The glossary page itself,
  which defines the terms, is exempt from this rule.)

:func:`out_of_step` compares the catalogues with the templates of a gettext build, for the test that
fails when a source has changed and the catalogues have not followed (``make translations``).
"""

from __future__ import annotations

import re
import sys
import unicodedata
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
GLOSSARY = ROOT / "book" / "glossary.md"

ROLE = re.compile(r"\{(?P<name>[\w:-]+)\}`(?P<body>[^`]*)`")
CODE = re.compile(r"(?<![`}])`(?P<body>[^`]+)`")
DISPLAY_MATH = re.compile(r"\$\$.+?\$\$", re.S)
INLINE_MATH = re.compile(r"(?<![\\$])\$(?!\$)(?P<body>[^$]+?)(?<!\\)\$")
LINK_TARGET = re.compile(r"\]\((?P<target>[^)\s]+)\)")
#: A number of an output's words, a parameter of its message (book/_ext/translatable.py): ``{1}``.
PLACEHOLDER = re.compile(r"(?<![{\w])\{\d+\}(?![}`])")
TARGET = re.compile(r"<(?P<target>[^<>]+)>\s*$")
#: Roles whose text is shown to the reader and may be translated; only their ``<target>`` must stay.
DISPLAY_ROLES = {"ref", "numref", "doc", "term", "download", "eq"}
#: Glossary terms that are also everyday words, and the contexts where they are the everyday word:
#: "link to the licence", "the link at the top of each page" are not links of a mechanism.
EVERYDAY = {"link": r"(?!\s+(?:to|at)\b)"}


def normal(text: str) -> str:
    """``text`` for comparing words: NFC, lower case, one kind of dash, single spaces."""
    text = unicodedata.normalize("NFC", text).lower()
    text = re.sub(r"\s*[-\u2010-\u2015\u2212]\s*", " - ", text)
    return re.sub(r"\s+", " ", text).strip()


def markup(text: str) -> Counter:
    """The parts of a message that a translation must keep unchanged, counted."""
    parts = Counter()
    for match in ROLE.finditer(text):
        name, body = match.group("name"), match.group("body")
        target = TARGET.search(body)
        if name in DISPLAY_ROLES:
            if target:
                parts[f"{{{name}}}<{target.group('target')}>"] += 1
            elif name != "term":                 # {term}`word` names the glossary entry by its own text
                parts[match.group(0)] += 1
        else:
            parts[match.group(0)] += 1
    rest = ROLE.sub(" ", text)
    for pattern in (DISPLAY_MATH, INLINE_MATH):
        for match in pattern.finditer(rest):
            parts[re.sub(r"\s+", " ", match.group(0))] += 1
        rest = pattern.sub(" ", rest)
    for match in CODE.finditer(rest):
        parts[match.group(0)] += 1
    for match in LINK_TARGET.finditer(rest):
        parts[f"]({match.group('target')})"] += 1
    for match in PLACEHOLDER.finditer(rest):
        parts[match.group(0)] += 1
    return parts


def prose(text: str) -> str:
    """``text`` without its markup: the words a reader reads."""
    for pattern in (ROLE, DISPLAY_MATH, INLINE_MATH, CODE, LINK_TARGET, PLACEHOLDER):
        text = pattern.sub(" ", text)
    return text


@dataclass(frozen=True)
class Term:
    """A glossary entry: the paper's Vietnamese term and the English term the book uses."""

    vietnamese: str
    english: str

    def pattern(self) -> re.Pattern:
        """The English term in running text: any case, each word also in the plural."""
        words = [re.escape(word) + r"(?:s|es)?" for word in re.split(r"[\s-]+", self.english)]
        return re.compile(r"(?<![\w-])" + r"[\s-]+".join(words) + r"(?![\w])" + EVERYDAY.get(self.english, ""),
                          re.I)


def glossary_terms(path: Path = GLOSSARY) -> list[Term]:
    """Every entry of the glossary page: its headword and the first bold English words under it."""
    text = path.read_text(encoding="utf-8")
    entries = re.finditer(r"^(?P<term>\S[^\n]*)\n  \*\*(?P<english>[^*]+)\*\*", text, re.M)
    terms = [Term(m.group("term").strip(), re.sub(r"\s*\(.*?\)", "", m.group("english")).strip())
             for m in entries]
    if len(terms) < 10:
        raise ValueError(f"{path} yields only {len(terms)} glossary terms: has its layout changed?")
    return terms


@dataclass(frozen=True)
class Problem:
    """One message that is not right, and why."""

    path: str
    line: int
    msgid: str
    reason: str

    def __str__(self):
        shown = self.msgid if len(self.msgid) < 90 else self.msgid[:87] + "..."
        return f"{self.path}:{self.line}: {self.reason}: {shown!r}"


def read_catalog(path: Path):
    from babel.messages.pofile import read_po

    with open(path, "rb") as handle:
        return read_po(handle, abort_invalid=True)


def is_display_math(msgid: str) -> bool:
    """A message that is a display equation (Sphinx extracts a math block's LaTeX as it stands)."""
    return msgid.startswith(("\n", "\\begin{")) and "$" not in msgid


TEXT_IN_MATH = re.compile(r"\\(?:text|mathrm|textrm)\{[^{}]*\}")


def problems(path: Path, terms: list[Term] | None = None) -> list[Problem]:
    """Every message of the catalogue at ``path`` that is untranslated, fuzzy, loses markup or a term."""
    terms = glossary_terms() if terms is None else terms
    if Path(path).stem == GLOSSARY.stem:        # the glossary defines the terms: its entries name both forms
        terms = []
    found = []
    for message in read_catalog(path):
        if not message.id:
            continue
        line = message.lineno or 0
        say = lambda reason: found.append(Problem(str(path), line, message.id, reason))  # noqa: E731
        if not message.string:
            say("not translated")
            continue
        if message.fuzzy:
            say("fuzzy (the source changed: check the translation and remove the fuzzy flag)")
        if is_display_math(message.id):       # the same equation; only the words of its \text{} may change
            if TEXT_IN_MATH.sub("", message.id).split() != TEXT_IN_MATH.sub("", message.string).split():
                say("a display equation changed outside its \\text{...}")
            continue
        lost, added = markup(message.id) - markup(message.string), markup(message.string) - markup(message.id)
        if lost or added:
            say(f"markup changed: missing {sorted(lost)}, extra {sorted(added)}")
        english, translated = prose(message.id), normal(message.string)
        for term in terms:
            if term.pattern().search(english) and normal(term.vietnamese) not in translated:
                say(f"the glossary's '{term.vietnamese}' for '{term.english}' is not used")
    return found


def display_equations(page_html: str) -> list[str]:
    """The display equations of a built page (site or single page), in order, each as the TeX it shows
    with the words of its ``\\text{}`` left out: the same list in every edition of a page.

    An equation whose translated TeX was lost shows as ``::`` or nothing; it is kept as it is, so
    that the comparison with the source edition sees it.
    """
    from bs4 import BeautifulSoup

    soup = BeautifulSoup(page_html, "html.parser")
    equations = []
    for node in soup.select("div.math"):
        tex = node.get_text().strip()
        tex = re.sub(r"^\\\[|\\\]$", "", tex).strip()
        equations.append(" ".join(TEXT_IN_MATH.sub(r"\\text{}", tex).split()))
    return equations


#: The interface catalogue of a language, ``<locale>/sphinx.po``: the site's words around the pages (the
#: theme's, Sphinx's, MyST-NB's buttons), in Sphinx's own text domain (book/_ext/translatable.py). It is
#: no page's catalogue, and `make translations` does not touch it.
INTERFACE = "sphinx"


def catalogues(locale: Path) -> dict[str, Path]:
    """``{page: .po path}`` of one language's folder, e.g. ``locales/vi/LC_MESSAGES`` (the interface
    catalogue, which is no page's, left out)."""
    return {str(path.relative_to(locale).with_suffix("")): path for path in sorted(locale.rglob("*.po"))
            if path.relative_to(locale).with_suffix("").as_posix() != INTERFACE}


def out_of_step(templates: Path, locale: Path) -> dict[str, str]:
    """Pages whose catalogue is missing, or whose messages differ from the gettext templates'.

    ``templates`` is the output folder of a gettext build (``.pot`` files), ``locale`` a language's
    ``LC_MESSAGES`` folder. Returns ``{page: what differs}``; empty when all are in step.
    """
    from babel.messages.pofile import read_po

    pots = {str(path.relative_to(templates).with_suffix("")): path for path in sorted(templates.rglob("*.pot"))}
    pos = catalogues(locale)
    differ = {}
    for page in sorted(set(pots) | set(pos)):
        if page not in pos:
            differ[page] = "no catalogue"
            continue
        if page not in pots:
            differ[page] = "a catalogue for a page the book no longer has"
            continue
        with open(pots[page], "rb") as handle:
            wanted = {message.id for message in read_po(handle) if message.id}
        have = {message.id for message in read_catalog(pos[page]) if message.id}
        new, gone = wanted - have, have - wanted
        if new or gone:
            differ[page] = f"{len(new)} new message(s), {len(gone)} no longer in the source"
    return differ


def main(argv: list[str]) -> int:
    if len(argv) < 2 or argv[0] != "check":
        print("usage: python book/_ext/translations.py check FILE.po ...", file=sys.stderr)
        return 2
    terms, total = glossary_terms(), []
    for name in argv[1:]:
        found = problems(Path(name), terms)
        total += found
        for problem in found:
            print(problem)
        count = sum(1 for message in read_catalog(Path(name)) if message.id)
        print(f"{name}: {count} messages, {len(found)} problem(s)")
    return 1 if total else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
