"""A comparison or bound that the prose of chapters 8 and 9 states holds as printed, in the build's run.

A glued number is rounded by the format spec the prose pastes it with (``{glue:text}`key:.2f` ``), and a
bound rounded the wrong way is false as printed: "below 2.3" above a value of 2.35. Each entry of
`BOUNDS` is ``(chapter, words of the sentence, left, relation, right)`` and reads "left relation right",
``relation`` one of ``<``, ``<=``, ``>``, ``>=``. Each side is a glue key or a number: on the left the
key's exact glued value, on the right its value *as the sentence prints it* (formatted with the
sentence's own format spec, which the sentence must paste). A bound is glued rounded the safe way (up
for an upper bound, down for a lower one) at the digits the page prints, and the value it bounds is
glued unrounded beside it (its key ends in ``-exact``). Both come from the build's own run of the
chapter: ``_build/jupyter_execute/chapters/<page>.glue.json``, where myst-nb keeps every value a page
glues.

So that no bound escapes the list, the chapters of `CHAPTERS` are read for sentences that paste a value
right after a bound word ("below", "above", "at most", "at least", "within", "holds to", "up to",
"under", "over", "more than", "less than", "fewer than") or with "or more" / "or less" after it: each
such key must be the right side of an entry.

(The same entry format as the chapters 2-7 bounds of issue 36: at a merge the entries can join one list.)
"""

from __future__ import annotations

import json
import operator
import re
from pathlib import Path

import pytest

from .test_prose_claims import markdown_and_code, sentence_with, sentences

ROOT = Path(__file__).resolve().parents[1]

#: The chapters whose every stated bound must be an entry of BOUNDS.
CHAPTERS = ("08-error-vs-runtime.md", "09-stiffness-and-long-runs.md")

#: (chapter file, words of the sentence, left, relation, right): "left relation right" holds in the build's run.
BOUNDS = [
    ("09-stiffness-and-long-runs.md", "just inside the edge", "ch09-rk45-loosest-alpha-h", "<", "ch09-rk45-edge"),
    ("09-stiffness-and-long-runs.md", "The rule lies inside the stable region",
     "ch09-rule-margin-exact", "<=", "ch09-rule-margin"),
]

_RELATIONS = {"<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge}
_ROLE = re.compile(r"\{glue(?::text)?\}`([^`:]+)(?::([^`]*))?`")
_BEFORE = re.compile(r"\b(?:below|above|at most|at least|within|holds? to|up to|under|over|more than|less than"
                     r"|fewer than)\s*$", re.I)
_AFTER = re.compile(r"^[^.;:]{0,40}?\bor (?:more|less)\b", re.I)


def glued_values(chapter):
    """``key -> value`` of every number glued in the build's run of a chapter."""
    path = ROOT / "_build" / "jupyter_execute" / "chapters" / chapter.replace(".md", ".glue.json")
    assert path.exists(), f"no glued values of {chapter} in the build ({path})"
    values = {}
    for key, output in json.loads(path.read_text()).items():
        text = "".join(output["data"]["text/plain"]).strip()
        found = re.fullmatch(r"(?:np\.\w+\()?([-+0-9.eE]+|inf|nan)\)?", text)
        if found:
            values[key] = float(found.group(1))
    return values


def as_printed(sentence, key, value):
    """``value`` as the sentence prints the glued ``key``: with its format spec, read back."""
    specs = {match.group(2) or "" for match in _ROLE.finditer(sentence) if match.group(1) == key}
    assert len(specs) == 1, f"the sentence pastes {key} with {len(specs)} format specs: {specs}"
    text = format(value, specs.pop())
    return float(text.rstrip("%")) / 100 if text.endswith("%") else float(text)


def side(value, values, sentence, left):
    if isinstance(value, str):
        assert value in values, f"no number glued as {value!r} in the build's run"
        return values[value] if left else as_printed(sentence, value, values[value])
    return float(value)


@pytest.mark.parametrize("chapter, words, left, relation, right", BOUNDS,
                         ids=[f"{b[2]}{b[3]}{b[4]}" for b in BOUNDS])
def test_a_stated_bound_holds_as_printed(built_site, chapter, words, left, relation, right):
    sentence = sentence_with(markdown_and_code(chapter)[0], words)
    values = glued_values(chapter)
    value, bound = side(left, values, sentence, True), side(right, values, sentence, False)
    assert _RELATIONS[relation](value, bound), (
        f"{chapter}: '{words}' states {left} {relation} {right}, printed {bound:g}, but {left} is {value!r}: "
        f"round the bound the safe way (up for an upper bound, down for a lower one): {sentence}")


def stated_bounds(sentence):
    """The glue keys that a sentence pastes as bounds, by the words around them."""
    for match in _ROLE.finditer(sentence):
        if _BEFORE.search(sentence[:match.start()]) or _AFTER.search(sentence[match.end():]):
            yield match.group(1)


@pytest.mark.parametrize("chapter", CHAPTERS)
def test_every_stated_bound_is_listed(chapter):
    listed = {right for file, _, _, _, right in BOUNDS if file == chapter}
    missing = [(key, sentence) for sentence in sentences(markdown_and_code(chapter)[0])
               for key in stated_bounds(sentence) if key not in listed]
    assert not missing, f"{chapter}: bounds stated in prose but not in BOUNDS: {missing}"


def test_the_bound_checks_can_fail():
    """A bound rounded the wrong way is caught, and the words that state a bound are found."""
    sentence = "Both runs hold |f| below {glue:text}`ch04-x:.1f` times the tolerance."
    assert as_printed(sentence, "ch04-x", 2.349) == 2.3 and not _RELATIONS["<="](2.35, 2.3)
    assert as_printed(sentence, "ch04-x", 2.35) == 2.4 and _RELATIONS["<="](2.35, 2.4)
    assert as_printed("steps of {glue:text}`k:.0f` or more", "k", 39.7) == 40.0 and not _RELATIONS[">="](39.7, 40)
    assert list(stated_bounds(sentence)) == ["ch04-x"]
    assert list(stated_bounds("a step more than {glue:text}`k:.2f` times as long")) == ["k"]
    assert list(stated_bounds("It takes {glue:text}`k:.0f` times 1/alpha or more.")) == ["k"]
    assert list(stated_bounds("It takes {glue:text}`k:.0f` times as long.")) == []
