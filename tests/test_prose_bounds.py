"""A bound that a chapter's prose states ("below X", "at most X", "X or more") holds for the value it bounds.

A glued number is rounded by the format spec the prose pastes it with (``{glue:text}`key:.1e` ``), and a bound
rounded the wrong way is false as printed: "below 2.3" above a value of 2.35. Each entry of `BOUNDS` names a
chapter, the glue key pasted as the bound, words of its sentence, whether the printed number is an upper bound
(the value is at most the printed number) or a lower bound (at least), and the glue key of the value it bounds.
That value is glued unrounded in the same hidden cell and not pasted (the key ends in ``-exact`` by
convention), or it is another pasted value that the sentence compares with the bound. The test formats the
bound as the prose pastes it, reads the printed number back, and compares it with the value, both from the
build's own run of the chapter (``_build/jupyter_execute/<page>.glue.json``, where myst-nb keeps every glued
value of a page).

So that no bound escapes the list, a second test reads the chapters in `CHAPTERS` and asks that every pasted
value preceded by a bound word ("below", "above", "at most", "at least", "within", "holds to", "up to",
"under", "over", "more than", "less than", "fewer than") or followed by "or more" / "or less" in its sentence be an entry. Chapters are added to
`CHAPTERS` as their bounds are listed.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

from .test_prose_claims import markdown_and_code, sentence_with, sentences

ROOT = Path(__file__).resolve().parents[1]

#: The chapters whose every stated bound must be an entry of BOUNDS.
CHAPTERS = ("08-error-vs-runtime.md", "09-stiffness-and-long-runs.md")

#: (chapter file, glue key pasted as the bound, words of its sentence, "upper" or "lower", glue key of the value)
BOUNDS = [
    ("09-stiffness-and-long-runs.md", "ch09-rk45-edge",
     "just inside the edge", "upper", "ch09-rk45-loosest-alpha-h"),
    ("09-stiffness-and-long-runs.md", "ch09-rule-margin",
     "The rule lies inside the stable region", "upper", "ch09-rule-margin-exact"),
]

_ROLE = re.compile(r"\{glue(?::text)?\}`([^`:]+)(?::([^`]*))?`")
_BEFORE = re.compile(r"\b(?:below|above|at most|at least|within|holds? to|up to|under|over|more than|less than"
                     r"|fewer than)\s*$", re.I)
_AFTER = re.compile(r"^[^.;:]{0,40}?\bor (?:more|less)\b", re.I)


def glued_values(chapter):
    """``key -> text/plain`` of every value glued in the build's run of a chapter."""
    path = ROOT / "_build" / "jupyter_execute" / "chapters" / chapter.replace(".md", ".glue.json")
    assert path.exists(), f"no glued values of {chapter} in the build ({path})"
    return {key: "".join(output["data"]["text/plain"]) for key, output in json.loads(path.read_text()).items()}


def number(text):
    """The number a glued value's text/plain shows (``1.5e-05``, ``np.float64(2.0)``, ``3``)."""
    found = re.fullmatch(r"(?:np\.\w+\()?([-+0-9.eE]+|inf|nan)\)?", text.strip())
    assert found, f"not a number: {text!r}"
    return float(found.group(1))


def printed(sentence, key, value):
    """The number the prose shows for ``key``: the value formatted by the sentence's format spec."""
    spec = next(match.group(2) or "" for match in _ROLE.finditer(sentence) if match.group(1) == key)
    return float(format(value, spec))


def holds(kind, bound, value):
    return value <= bound if kind == "upper" else value >= bound


@pytest.mark.parametrize("chapter, key, words, kind, value_key", BOUNDS, ids=[entry[1] for entry in BOUNDS])
def test_a_stated_bound_holds_as_printed(built_site, chapter, key, words, kind, value_key):
    sentence = sentence_with(markdown_and_code(chapter)[0], words)
    values = glued_values(chapter)
    bound = printed(sentence, key, number(values[key]))
    value = number(values[value_key])
    assert holds(kind, bound, value), (
        f"{chapter}: the prose prints {key} as {bound:g}, an {kind} bound, but the value is {value!r}: "
        f"round it the safe way (up for an upper bound, down for a lower one) in: {sentence}")


def stated_bounds(sentence):
    """The glue keys that a sentence states as bounds, by the words around them."""
    for match in _ROLE.finditer(sentence):
        if _BEFORE.search(sentence[:match.start()]) or _AFTER.search(sentence[match.end():]):
            yield match.group(1)


@pytest.mark.parametrize("chapter", CHAPTERS)
def test_every_stated_bound_is_listed(chapter):
    listed = {key for file, key, *_ in BOUNDS if file == chapter}
    missing = [(key, sentence) for sentence in sentences(markdown_and_code(chapter)[0])
               for key in stated_bounds(sentence) if key not in listed]
    assert not missing, f"{chapter}: bounds stated in prose but not in BOUNDS: {missing}"


def test_the_bound_checks_can_fail():
    """A bound rounded the wrong way is caught, and the words that state a bound are found."""
    sentence = "Both runs hold |f| below {glue:text}`ch04-x:.1f` times the tolerance."
    assert printed(sentence, "ch04-x", 2.35) == 2.4 and holds("upper", 2.4, 2.35)
    assert printed(sentence, "ch04-x", 2.34) == 2.3 and not holds("upper", 2.3, 2.35)
    assert not holds("lower", printed("steps of {glue:text}`k:.0f` or more", "k", 39.7), 39.7)
    assert list(stated_bounds(sentence)) == ["ch04-x"]
    assert list(stated_bounds("It takes {glue:text}`k:.0f` times 1/alpha or more.")) == ["k"]
    assert list(stated_bounds("It takes {glue:text}`k:.0f` times as long.")) == []
    assert number("np.float64(1.5e-05)") == 1.5e-05 and number("3") == 3.0
