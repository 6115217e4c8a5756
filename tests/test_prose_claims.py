"""Numbers that the chapters' prose states about a computed result are glued from the computation.

Each entry of `CLAIMS` names a chapter, a glue key and a few words of the sentence that states the
number. For each claim the test checks, without executing the chapter (the book's build executes it,
and with ``-W`` a glue key that no cell produces, or a value its format spec cannot take, fails the
build):

- the sentence exists in a markdown cell and pastes the key with ``{glue:text}`key...` `` (or
  ``{glue}`key` ``);
- a code cell of the same chapter calls ``glue("key", ...)``;
- no digit is typed by hand in the sentence outside math, code, roles and links, except the input
  numbers the claim lists (a time span, a case number): a result retyped beside or instead of the
  glued value fails.
"""

import functools
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

#: (chapter file, glue key, words of the sentence, digits the sentence may hold as inputs)
CLAIMS = [
    ("02-lagrange-multipliers.md", "ch02-vertical-over-half-weight",
     "presses the slider down onto its guide", ()),
    ("02-lagrange-multipliers.md", "ch02-lambda1-negative-from",
     "is negative around the outer dead centre", ()),
    ("02-lagrange-multipliers.md", "ch02-lambda1-negative-to",
     "is negative around the outer dead centre", ()),
    ("02-lagrange-multipliers.md", "ch02-position-drift-exponent",
     "Both exponents", ()),
    ("02-lagrange-multipliers.md", "ch02-velocity-drift-exponent",
     "Both exponents", ()),
    ("03-baumgarte.md", "ch03-nfev-doubling",
     "Larger gains cost more right-hand-side evaluations", ("10", "20")),
    ("03-baumgarte.md", "ch03-largest-alpha-h",
     "In every row", ()),
    ("03-baumgarte.md", "ch03-alpha-h-at-5",
     "In every row", ()),
    ("03-baumgarte.md", "ch03-alpha-h-at-50",
     "In every row", ()),
    ("04-orthogonality.md", "ch04-distance-over-tolerance",
     "both stay within", ()),
    ("04-orthogonality.md", "ch04-residual-over-tolerance",
     "both hold", ()),
    ("04-orthogonality.md", "ch04-call-time-ratio",
     "the orthogonal right-hand side does more work per call", ()),
    ("04-orthogonality.md", "ch04-largest-multiplier",
     "the constraint forces reach", ("2",)),
    ("04-orthogonality.md", "ch04-largest-cond-phi-z",
     "is well conditioned all the way round", ()),
    ("05-slider-crank-model.md", "ch05-gas-per-stroke",
     "One outward stroke takes out", ()),
    ("05-slider-crank-model.md", "ch05-torque-per-turn",
     "One outward stroke takes out", ()),
    ("06-four-cases.md", "ch06-case1-excursion",
     "swings up beyond the horizontal on the other side", ()),
    ("06-four-cases.md", "ch06-case2-slowest",
     "Starting with the potential energy of the top", ()),
    ("06-four-cases.md", "ch06-case2-revolutions",
     "Starting with the potential energy of the top", ()),
    ("06-four-cases.md", "ch06-case3-farthest",
     "The first swing is smaller than in case 1", ("1",)),
    ("06-four-cases.md", "ch06-case4-slowest",
     "the speed dips on every", ("1",)),
    ("06-four-cases.md", "ch06-largest-residual",
     "In all four runs", ("20",)),
    ("06-four-cases.md", "ch06-thousands-stuck-by",
     "The two matches of `thousands-opposing` are hollow", ()),
    ("06-four-cases.md", "ch06-torque-share",
     "Over that half turn the torque supplies only", ()),
    ("06-four-cases.md", "ch06-deficit",
     "Read as decimals, that deficit", ()),
    ("06-four-cases.md", "ch06-gravity-amplitude",
     "Read as decimals, that deficit", ()),
    ("06-four-cases.md", "ch06-smallest-kinetic",
     "Read as decimals, that deficit", ()),
    ("06-four-cases.md", "ch06-largest-kinetic",
     "Read as decimals, that deficit", ()),
    ("06-four-cases.md", "ch06-thousands-deficit-kj",
     "Read as thousands, the deficit is", ()),
    ("06-four-cases.md", "ch06-thousands-deficit-low",
     "Read as thousands, the deficit is", ()),
    ("06-four-cases.md", "ch06-thousands-deficit-high",
     "Read as thousands, the deficit is", ()),
    ("06-four-cases.md", "ch06-printed-runaway-by",
     "With thousands it does so beside a huge torque", ()),
    ("06-four-cases.md", "ch06-case1-sticks-at",
     "Both swings decay and then freeze", ("1", "3")),
    ("06-four-cases.md", "ch06-case3-sticks-at",
     "Both swings decay and then freeze", ("1", "3")),
    ("06-four-cases.md", "ch06-case3-torque-push",
     "in case 3 only just", ("3",)),
    ("10-singularities-and-switches.md", "ch10-nullspace-residual",
     "at each grey line", ()),
    ("10-singularities-and-switches.md", "ch10-naive-overshoot",
     "the budget of evaluations runs out at most", ("200",)),
    ("10-singularities-and-switches.md", "ch10-sticking-time-spread",
     "The numbers above say", ("1", "3")),
    ("10-singularities-and-switches.md", "ch10-final-phi-spread",
     "The numbers above say", ("1", "3")),
    ("11-energy.md", "ch11-gas-per-cycle",
     "compute the torque's work per crank turn and the gas force's work per slider cycle", ()),
    ("11-energy.md", "ch11-turn-cycle-gap",
     "The torque puts in, per turn, what the gas takes out per cycle", ()),
    ("11-energy.md", "ch11-rotating-gain-low",
     "tightening the integrator shrinks the residual", ("2", "4")),
    ("11-energy.md", "ch11-rotating-gain-high",
     "tightening the integrator shrinks the residual", ("2", "4")),
    ("11-energy.md", "ch11-largest-ripple-per-turn",
     "Every turn of a rotating crank nearly balances", ("1",)),
    ("11-energy.md", "ch11-thousands-works-kj",
     "The two works are each a thousand times larger", ()),
    ("11-energy.md", "ch11-thousands-largest-slope",
     "The largest slope of $\\Pi$ is", ()),
    ("11-energy.md", "ch11-thousands-torque-over-slope",
     "The largest slope of $\\Pi$ is", ()),
    ("12-basins.md", "ch12-stuck-swings",
     "swings have already come to rest", ()),
    ("12-basins.md", "ch12-swings",
     "swings have already come to rest", ()),
    ("12-basins.md", "ch12-most-changes",
     "swings have already come to rest", ()),
    ("12-basins.md", "ch12-widest-swing-dphi0",
     "The widest swing starts with", ()),
    ("12-basins.md", "ch12-widest-swing-phi0",
     "The widest swing starts with", ()),
    ("12-basins.md", "ch12-lowest-order",
     "The error falls at close to the fourth order of RK4", ("4",)),
    ("12-basins.md", "ch12-highest-order",
     "The error falls at close to the fourth order of RK4", ("4",)),
    ("12-basins.md", "ch12-margin-over-error",
     "At the step of the maps (grey line) the error is", ()),
    ("12-basins.md", "ch12-map-step",
     "Why, then, can a fixed step of", ()),
    ("12-basins.md", "ch12-zoom-most-changes",
     "At the finer resolution the boundary is still a single curve", ()),
    ("13-four-bar.md", "ch13-cond-phi-z-growth",
     "towards the change points", ()),
    ("13-four-bar.md", "ch13-cond-augmented-growth",
     "towards the change points", ()),
    ("13-four-bar.md", "ch13-largest-pendulum-error",
     "short of the change point every formulation agrees", ()),
    ("13-four-bar.md", "ch13-largest-energy-drift",
     "short of the change point every formulation agrees", ()),
    ("13-four-bar.md", "ch13-turning-vs-limit",
     "the null-space formulation turns the crank back", ()),
    ("13-four-bar.md", "ch13-tolerances-stopped",
     "of the four runs stop at the change point", ()),
    ("13-four-bar.md", "ch13-tolerances-went-on",
     "of the four runs stop at the change point", ()),
    ("13-four-bar.md", "ch13-redundant-stop-gap",
     "redundant ones stop within", ()),
    ("13-four-bar.md", "ch13-minimal-stop-gap",
     "Minimal stops with the same diagnosis", ()),
    ("07-conclusions.md", "ch07-gravity-amplitude",
     "Notice: gravity makes a barrier", ()),
    ("07-conclusions.md", "ch07-gas-per-stroke",
     "the gas resists most near the end of the stroke", ()),
    ("07-conclusions.md", "ch07-largest-balance-residual",
     "Notice: the balance (7.b) holds to", ()),
    ("07-conclusions.md", "ch07-case2-energy-change",
     "In the rotating cases 2 and 4 the two nearly cancel", ("2", "4", "20")),
    ("07-conclusions.md", "ch07-case4-energy-change",
     "In the rotating cases 2 and 4 the two nearly cancel", ("2", "4", "20")),
    ("07-conclusions.md", "ch07-case1-energy-change",
     "In the swinging cases 1 and 3", ("1", "3")),
    ("07-conclusions.md", "ch07-case3-energy-change",
     "In the swinging cases 1 and 3", ("1", "3")),
    ("07-conclusions.md", "ch07-ripple-per-turn",
     "This neglects only the torque ripple", ()),
    ("07-conclusions.md", "ch07-turn-stroke-gap",
     "The torque per turn and the gas per stroke agree to within", ()),
    ("07-conclusions.md", "ch07-torque-per-turn",
     "a running one gains the torque's", ()),
    ("08-error-vs-runtime.md", "ch08-library-best-label",
     "The short answer, which the chapter builds up", ()),
    ("08-error-vs-runtime.md", "ch08-library-best-method",
     "The short answer, which the chapter builds up", ()),
    ("08-error-vs-runtime.md", "ch08-baseline-best-printer",
     "The short answer, which the chapter builds up", ()),
    ("08-error-vs-runtime.md", "ch08-baseline-best-method",
     "The short answer, which the chapter builds up", ()),
    ("08-error-vs-runtime.md", "ch08-ratio-low",
     "The short answer, which the chapter builds up", ()),
    ("08-error-vs-runtime.md", "ch08-ratio-high",
     "The short answer, which the chapter builds up", ()),
    ("08-error-vs-runtime.md", "ch08-compiled-extra-evaluations",
     "Notice that the compiled method spends", ()),
    ("08-error-vs-runtime.md", "ch08-largest-reference-agreement",
     "s the largest of these is", ()),
    ("08-error-vs-runtime.md", "ch08-case2-reference-agreement",
     "it agrees to", ("2", "10")),
    ("08-error-vs-runtime.md", "ch08-numpy-ratio-low",
     "Notice the printer", ()),
    ("08-error-vs-runtime.md", "ch08-numpy-ratio-high",
     "Notice the printer", ()),
    ("08-error-vs-runtime.md", "ch08-printer-low",
     "Notice the printer", ()),
    ("08-error-vs-runtime.md", "ch08-printer-high",
     "Notice the printer", ()),
    ("08-error-vs-runtime.md", "ch08-book-route-low",
     "way at its best their ratio is", ()),
    ("08-error-vs-runtime.md", "ch08-book-route-high",
     "way at its best their ratio is", ()),
    ("08-error-vs-runtime.md", "ch08-closed-route-low",
     "With the closed form the ratio is", ()),
    ("08-error-vs-runtime.md", "ch08-closed-route-high",
     "With the closed form the ratio is", ()),
    ("08-error-vs-runtime.md", "ch08-augmented-over-math",
     "Notice that an evaluation of the augmented system (12) costs", ()),
    ("08-error-vs-runtime.md", "ch08-math-over-closed-form",
     "An evaluation of the usual way costs", ()),
    ("08-error-vs-runtime.md", "ch08-math-over-compiled",
     "An evaluation of the usual way costs", ()),
    ("08-error-vs-runtime.md", "ch08-baseline-tightest-cases",
     "The usual way reaches $e_{10}", ()),
    ("08-error-vs-runtime.md", "ch08-library-tightest-cases",
     "The usual way reaches $e_{10}", ()),
    ("08-error-vs-runtime.md", "ch08-curves",
     "Of the study's", ()),
    ("08-error-vs-runtime.md", "ch08-curves-at-time-cap",
     "Of the study's", ()),
    ("08-error-vs-runtime.md", "ch08-curves-at-error-floor",
     "Of the study's", ()),
    ("08-error-vs-runtime.md", "ch08-growth-low",
     "every row grows with the tolerance", ()),
    ("08-error-vs-runtime.md", "ch08-growth-high",
     "every row grows with the tolerance", ()),
    ("08-error-vs-runtime.md", "ch08-fastest-root",
     "At the study's gains, whose fastest root is", ("3",)),
    ("08-error-vs-runtime.md", "ch08-gain-step-cost",
     "The gains cost steps all the same", ()),
    ("08-error-vs-runtime.md", "ch08-levels",
     "ch08-levels:d` levels,", ()),
    ("08-error-vs-runtime.md", "ch08-cheapest-all-label",
     "ch08-levels:d` levels,", ()),
    ("08-error-vs-runtime.md", "ch08-cheapest-all-method",
     "ch08-levels:d` levels,", ()),
    ("08-error-vs-runtime.md", "ch08-cheapest-all-count",
     "ch08-levels:d` levels,", ()),
    ("08-error-vs-runtime.md", "ch08-cheapest-book-label",
     "Among the book's own formulations with", ()),
    ("08-error-vs-runtime.md", "ch08-cheapest-book-method",
     "Among the book's own formulations with", ()),
    ("08-error-vs-runtime.md", "ch08-cheapest-book-count",
     "Among the book's own formulations with", ()),
    ("08-error-vs-runtime.md", "ch08-main-case-methods",
     "In case 2, where every method runs", ("2",)),
    ("09-stiffness-and-long-runs.md", "ch09-rk45-tenfold-growth",
     "the explicit methods' step count grows steeply", ()),
    ("09-stiffness-and-long-runs.md", "ch09-dop853-tenfold-growth",
     "the explicit methods' step count grows steeply", ()),
    ("09-stiffness-and-long-runs.md", "ch09-radau-growth",
     "the explicit methods' step count grows steeply", ()),
    ("09-stiffness-and-long-runs.md", "ch09-rk45-tight-growth",
     "At tight tolerances its step still follows the tolerance", ()),
    ("09-stiffness-and-long-runs.md", "ch09-rk45-tightest-alpha-h",
     "At tight tolerances its step still follows the tolerance", ()),
    ("09-stiffness-and-long-runs.md", "ch09-rk45-loose-growth",
     "At loose tolerances it no longer does", ()),
    ("09-stiffness-and-long-runs.md", "ch09-rk45-loosest-alpha-h",
     "At loose tolerances it no longer does", ()),
    ("09-stiffness-and-long-runs.md", "ch09-rk45-edge",
     "At loose tolerances it no longer does", ()),
    ("09-stiffness-and-long-runs.md", "ch09-radau-smallest-alpha-h",
     "Radau, stable for any step", ()),
    ("09-stiffness-and-long-runs.md", "ch09-radau-largest-alpha-h",
     "Radau, stable for any step", ()),
    ("09-stiffness-and-long-runs.md", "ch09-radau-advantage",
     "Radau, stable for any step", ()),
    ("09-stiffness-and-long-runs.md", "ch09-map-agreement",
     "the linear theory of", ()),
    ("09-stiffness-and-long-runs.md", "ch09-map-cells",
     "the linear theory of", ()),
    ("09-stiffness-and-long-runs.md", "ch09-step-ratio-high",
     "a fourfold rise in speed", ("50", "200")),
    ("09-stiffness-and-long-runs.md", "ch09-step-ratio-low",
     "at the paper's speed the step is not set by the rotation alone", ("1.5", "50")),
    ("09-stiffness-and-long-runs.md", "ch09-rk45-error-slow",
     "The error of the crank angle grows", ("1.5", "200")),
    ("09-stiffness-and-long-runs.md", "ch09-rk45-error-fast",
     "The error of the crank angle grows", ("1.5", "200")),
    ("09-stiffness-and-long-runs.md", "ch09-lsoda-over-rk45",
     "Nothing here is stiff", ("200",)),
    ("09-stiffness-and-long-runs.md", "ch09-crossings",
     "Every run that finishes counts", ()),
    ("09-stiffness-and-long-runs.md", "ch09-augmented-drift",
     "only the augmented system's drift keeps growing", ()),
    ("09-stiffness-and-long-runs.md", "ch09-baumgarte-drift",
     "only the augmented system's drift keeps growing", ()),
    ("09-stiffness-and-long-runs.md", "ch09-minimal-drift",
     "only the augmented system's drift keeps growing", ()),
    ("09-stiffness-and-long-runs.md", "ch09-baumgarte-balance",
     "So the largest residual is", ()),
    ("09-stiffness-and-long-runs.md", "ch09-minimal-balance",
     "So the largest residual is", ()),
    ("09-stiffness-and-long-runs.md", "ch09-augmented-balance",
     "So the largest residual is", ()),
    ("09-stiffness-and-long-runs.md", "ch09-work-low",
     "of the four runs lie between", ()),
    ("09-stiffness-and-long-runs.md", "ch09-work-high",
     "of the four runs lie between", ()),
    ("09-stiffness-and-long-runs.md", "ch09-minimal-steps",
     "the minimal formulation is not the most accurate", ("1000",)),
    ("09-stiffness-and-long-runs.md", "ch09-baumgarte-steps",
     "the minimal formulation is not the most accurate", ("1000",)),
    ("09-stiffness-and-long-runs.md", "ch09-minimal-phase",
     "the minimal formulation is not the most accurate", ("1000",)),
    ("09-stiffness-and-long-runs.md", "ch09-baumgarte-phase",
     "the minimal formulation is not the most accurate", ("1000",)),
    ("09-stiffness-and-long-runs.md", "ch09-largest-condition",
     "The condition numbers reach", ()),
    ("09-stiffness-and-long-runs.md", "ch09-largest-relative-error",
     "The condition numbers reach", ()),
    ("09-stiffness-and-long-runs.md", "ch09-largest-scaled",
     "The large numbers are a matter of units", ()),
    ("09-stiffness-and-long-runs.md", "ch09-heavy-slider-m-max",
     "Notice the heavy slider's two deep notches", ("0", "180")),
    ("09-stiffness-and-long-runs.md", "ch09-heavy-slider-m-min",
     "Notice the heavy slider's two deep notches", ("0", "180")),
    ("09-stiffness-and-long-runs.md", "ch09-heavy-slider-speed-ratio",
     "Notice the heavy slider's two deep notches", ("0", "180")),
    ("09-stiffness-and-long-runs.md", "ch09-whip-speed",
     "The crank whips through each dead centre", ()),
    ("09-stiffness-and-long-runs.md", "ch09-whip-radau-ratio",
     "The crank whips through each dead centre", ()),
    ("09-stiffness-and-long-runs.md", "ch09-whip-bdf-ratio",
     "The crank whips through each dead centre", ()),
    ("09-stiffness-and-long-runs.md", "ch09-whip-better-explicit",
     "The crank whips through each dead centre", ()),
    ("09-stiffness-and-long-runs.md", "ch09-rule-margin",
     "The rule lies inside the stable region", ()),
]

#: What may hold digits without being a typed result: display and inline math, inline code,
#: roles with their content (glue, ref, doc, cite, ...), Markdown links, and equation numbers
#: written as the book writes them, "(26)" or "(7.b)".
_NOT_PROSE = re.compile(r"\$\$.*?\$\$|\$[^$]*\$|\{[\w:-]+\}`[^`]*`|`[^`]*`|\[[^\]]*\]\([^)]*\)"
                        r"|\(\d+(?:\.[a-z])?\)", re.S)
#: A sentence ends at '.', '!' or '?' (perhaps closing a parenthesis) followed by white space and
#: a capital, a role, math, code or a parenthesis.
_SENTENCE_END = re.compile(r"(?:(?<=[.!?])|(?<=[.!?]\)))\s+(?=[A-Z{$`(])")


@functools.cache
def markdown_and_code(chapter):
    """The markdown cells and the code cells of a chapter, as tuples of source strings."""
    import jupytext

    notebook = jupytext.read(ROOT / "chapters" / chapter)
    cells = {"markdown": [], "code": []}
    for cell in notebook.cells:
        if cell.cell_type in cells:
            cells[cell.cell_type].append(cell.source)
    return tuple(cells["markdown"]), tuple(cells["code"])


def sentences(markdown):
    """Every sentence of the markdown cells, with its white space collapsed."""
    for source in markdown:
        for paragraph in re.split(r"\n\s*\n|\n(?=\s*(?:[-*]|\d+\.) )", source):  # list items apart
            text = " ".join(paragraph.split())
            yield from _SENTENCE_END.split(text)


def sentence_with(markdown, words):
    """The one sentence that contains `words`."""
    found = [s for s in sentences(markdown) if words in s]
    assert len(found) == 1, f"{len(found)} sentences contain {words!r}"
    return found[0]


def pastes(sentence, key):
    """Whether the sentence pastes the glue key (with or without a format spec)."""
    return re.search(r"\{glue(?::text)?\}`" + re.escape(key) + r"(:[^`]*)?`", sentence) is not None


def typed_digits(sentence):
    """The numbers typed in the sentence's prose, outside math, code, roles and link targets."""
    return re.findall(r"(?<![A-Za-z\d])\d+(?:[.,]\d+)*", _NOT_PROSE.sub(" ", sentence))  # not RK45


def defines(code, key):
    """Whether a code cell calls glue with this key, as a string literal or an f-string in a loop."""
    for source in code:
        for literal in re.findall(r"\bglue\(\s*f?[\"']([^\"']+)[\"']", source):
            pattern = re.escape(literal).replace(r"\{", "{").replace(r"\}", "}")
            if re.fullmatch(re.sub(r"\{[^}]*\}", r"[^-]+", pattern), key):
                return True
    return False


@pytest.mark.parametrize("chapter, key, words, allowed", CLAIMS, ids=[c[1] for c in CLAIMS])
def test_claim_is_glued_from_the_computation(chapter, key, words, allowed):
    markdown, code = markdown_and_code(chapter)
    sentence = sentence_with(markdown, words)
    assert pastes(sentence, key), f"{chapter}: the sentence does not paste {key}: {sentence}"
    assert defines(code, key), f"{chapter}: no code cell calls glue({key!r}, ...)"
    typed = [number for number in typed_digits(sentence) if number not in allowed]
    assert not typed, f"{chapter}: hand-typed numbers {typed} in: {sentence}"
    unused = set(allowed) - set(typed_digits(sentence))
    assert not unused, f"{chapter}: allowed inputs {unused} no longer in: {sentence}"


def test_keys_are_unique_and_named_after_their_chapter():
    keys = [key for _, key, _, _ in CLAIMS]
    assert len(set(keys)) == len(keys)
    for chapter, key, _, _ in CLAIMS:
        assert key.startswith(f"ch{chapter[:2]}-"), key


def test_every_glued_key_of_a_chapter_is_a_listed_claim():
    """A number pasted into prose but missing here would escape the checks above."""
    listed = {(chapter, key) for chapter, key, _, _ in CLAIMS}
    for path in sorted((ROOT / "chapters").glob("*.md")):
        markdown, _ = markdown_and_code(path.name)
        for source in markdown:
            for key in re.findall(r"\{glue(?::text)?\}`([^`:]+)", source):
                assert (path.name, key) in listed, f"{path.name} pastes {key}, not in CLAIMS"


@pytest.mark.parametrize("sentence, key, typed", [
    ("It takes {glue:text}`ch09-x:.2f` s.", "ch09-x", []),
    ("It takes {glue:text}`ch09-x:.2f` s, about 15 times.", "ch09-x", ["15"]),
    ("It takes 0.25 s ({glue:text}`ch09-x`).", "ch09-x", ["0.25"]),
    ("With $\\alpha = 5$ and `rtol=1e-9` ([(16)](eq-16)) it takes {glue}`ch09-x`.", "ch09-x", []),
    ("By (7.b) it changes by {glue:text}`ch09-x:.0f` J, not 7.5 J.", "ch09-x", ["7.5"]),
    ("With RK45 and DOP853 it takes {glue:text}`ch09-x:.1f` s, not 15 s.", "ch09-x", ["15"]),
])
def test_the_checks_see_a_retyped_number(sentence, key, typed):
    """The helpers find a glued key and a hand-typed number, and skip math, code and links."""
    assert pastes(sentence, key)
    assert typed_digits(sentence) == typed
    assert not pastes(sentence.replace(key, "ch09-y"), key)


def test_glue_calls_are_found_as_literals_and_as_f_strings():
    code = ('glue("ch07-gap", gap, display=False)',
            'for n in (1, 2):\n    glue(f"ch07-case{n}-change", x[n], display=False)')
    assert defines(code, "ch07-gap") and defines(code, "ch07-case2-change")
    assert not defines(code, "ch07-case2-other") and not defines(code, "ch07-ga")


#: Every page that is a notebook (MyST Markdown with a jupytext header): chapters, exercises, front and back matter.
PAGES = sorted(page for folder in ("chapters", "exercises", "book") for page in (ROOT / folder).glob("*.md")
               if page.read_text().startswith("---\njupytext:"))


@pytest.mark.parametrize("page", PAGES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_no_cell_the_reader_sees_glues(page):
    """A value pasted into the prose is glued in a cell tagged ``remove-cell``: the page, the PDF and the
    download leave it out, so the reader's code holds the physics and never the build's plumbing."""
    import jupytext

    notebook = jupytext.read(page)
    seen = [cell.source for cell in notebook.cells if cell.cell_type == "code"
            and "remove-cell" not in cell.metadata.get("tags", [])]
    assert not [s for s in seen if re.search(r"\bglue\b|myst_nb", s)], \
        f"{page.name}: a cell the reader sees calls glue (tag it remove-cell, or move the glue into one that is)"


def test_the_glue_detector_sees_a_visible_glue(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("---\njupytext:\n  text_representation:\n    extension: .md\n    format_name: myst\n---\n\n"
                    "```{code-cell} ipython3\nfrom myst_nb import glue\nglue('k', 1)\n```\n")
    with pytest.raises(AssertionError, match="calls glue"):
        test_no_cell_the_reader_sees_glues(page)
