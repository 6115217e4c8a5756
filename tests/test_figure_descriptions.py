"""What a figure's description (its alt text) says of computed numbers holds in the build's outputs.

An alt text cannot paste a glued value, so the few that state computed results in words are
checked here against the table the same chapter printed in the build (the executed notebook the
site offers for download, ``_build/html/_sources/<page>.ipynb``). The other alt texts describe
inputs (Table 1, the force law) or shapes, not computed figures.

Chapter 9, the Baumgarte gains: "The explicit methods RK45 and DOP853 ... rise steeply, about six-
to sevenfold per tenfold gain from α = 10 on. ... Radau grows only slowly; LSODA rises almost as
steeply as the explicit methods from 10 to 1000 and then levels off, and BDF grows slowly up to
1000 and then steeply, about eightfold, to 10000."
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CHAPTER_9 = "chapters/09-stiffness-and-long-runs"
#: The words of chapter 9's alt text that state the counts checked below.
GAINS_WORDS = ("about six- to sevenfold per tenfold gain from α = 10 on", "Radau grows only slowly",
               "LSODA rises almost as steeply as the explicit methods from 10 to 1000 and then levels off",
               "BDF grows slowly up to 1000 and then steeply, about eightfold, to 10000")


@pytest.fixture(scope="module")
def gains_table(built_site):
    """Chapter 9's printed table of accepted steps: ``{method: [steps at alpha = 1, 10, 100, 1e3, 1e4]}``."""
    notebook = json.loads((ROOT / "_build" / "html" / "_sources" / f"{CHAPTER_9}.ipynb").read_text())
    for cell in notebook["cells"]:
        for output in cell.get("outputs", []):
            text = "".join(output.get("data", {}).get("text/plain", ""))
            if text.startswith("method") and "a = b = 10000" in text:
                rows = [line.split() for line in text.splitlines()[1:]]
                return {row[0]: [int(v) for v in row[1:6]] for row in rows}
    raise AssertionError(f"no table of steps against the gains in {CHAPTER_9}'s outputs")


def growth(counts):
    """The factor by which each tenfold gain multiplies the steps: four ratios."""
    return [b / a for a, b in zip(counts, counts[1:])]


def test_the_gains_figure_states_what_its_description_checks():
    source = (ROOT / f"{CHAPTER_9}.md").read_text()
    alt = next(a for a in re.findall(r'alt: "([^"]*)"', source) if a.startswith("Accepted steps"))
    for words in GAINS_WORDS:
        assert words in alt, f"the alt text no longer says {words!r}: update this test with it"


def test_the_explicit_methods_grow_six_to_sevenfold_per_tenfold_gain(gains_table):
    for method in ("RK45", "DOP853"):
        ratios = growth(gains_table[method])[1:]           # from alpha = 10 on
        assert all(5.5 <= r < 7.5 for r in ratios), (method, ratios)


def test_the_implicit_methods_grow_as_the_description_says(gains_table):
    radau, lsoda, bdf = (growth(gains_table[m]) for m in ("Radau", "LSODA", "BDF"))
    explicit = [min(a, b) for a, b in zip(growth(gains_table["RK45"]), growth(gains_table["DOP853"]))]
    assert all(r < 0.6 * e for r, e in zip(radau[1:], explicit[1:])), (radau, explicit)   # only slowly
    assert all(r >= 4.0 for r in lsoda[1:3]) and lsoda[3] < 1.5, lsoda    # steep to 1000, then level
    assert all(r < 2.5 for r in bdf[:3]) and 7.5 <= bdf[3] < 8.5, bdf     # slow to 1000, then ~8x
