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

Each entry of `BOUNDS` is a comparison that a sentence states ("|f| never exceeds X", "stays within
X times the tolerance", "lies between 3/2 and 2", "case 1 brings more than the deficit", "at least
X times as many steps"), for every chapter; the test checks it against the build's own run of the
chapter (its executed notebook in the execution cache, so it needs the built book):
``(chapter, words of the sentence, left, relation, right)`` reads "left relation right", with
relation one of ``<``, ``<=``, ``>``, ``>=``. Each side is

- a glue key: on the right, the value *as the sentence prints it*, formatted with every format spec
  the chapter's prose pastes it with (``{glue:text}`key:.2f```); on the left, the exact glued
  value, and also the value as printed if the prose pastes it. A bound is glued from
  ``closedloop.plotting.rounded_bound``, which rounds up an upper bound (down a lower one) at the
  digits the page prints, and the value it bounds is glued unrounded beside it, under the key of
  the bound with ``-exact`` appended (both in the hidden cell);
- ``Printed(pattern, scale)``: every number the chapter's code cells print that the pattern's
  first group matches (times ``scale``), each of which must satisfy the relation; a pattern that
  matches nothing fails;
- a number: an input of the sentence (``1.5`` for "3/2").

So that no bound escapes the list, every chapter's prose is read for values pasted right after a
bound word ("below", "above", "at most", "at least", "within", "up to", "more than", "exceeds",
"(to X", "agrees ... to X", "keeps ... to X", ...), before "or more" / "or less" / "or better", or
continuing such a bound ("to X s and Y rad"): each must be the right side of an entry, or be listed
in `NOT_BOUNDS` with the reason it bounds nothing (a value stated after "to", an input). Every
``-exact`` value a chapter glues must be a side of an entry.

To check a new sentence: glue its bound with `rounded_bound` and the exact value beside it in a
hidden cell, and add an entry.
"""

import functools
import math
import operator
import re
from dataclasses import dataclass
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
    ("03-baumgarte.md", "ch03-residual-ratio",
     "lowers the largest", ()),
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
     "the constraint forces reach", ()),
    ("04-orthogonality.md", "ch04-largest-power",
     "the constraint forces reach", ()),
    ("04-orthogonality.md", "ch04-largest-cond-phi-z",
     "is well conditioned all the way round", ()),
    ("05-slider-crank-model.md", "ch05-ripple-share",
     "Next to the mean it is tiny", ()),
    ("05-slider-crank-model.md", "ch05-gas-per-stroke",
     "One outward stroke takes out", ()),
    ("05-slider-crank-model.md", "ch05-torque-per-turn",
     "One outward stroke takes out", ()),
    ("06-four-cases.md", "ch06-case1-excursion",
     "swings up beyond the horizontal on the other side", ()),
    ("06-four-cases.md", "ch06-three-quarter-turn",
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
    ("06-four-cases.md", "ch06-top-bar",
     "the bar stands at", ("1.5", "4", "1")),
    ("06-four-cases.md", "ch06-case1-kinetic",
     "the bar stands at", ("1.5", "4", "1")),
    ("06-four-cases.md", "ch06-case3-torque-push",
     "in case 3 only just", ("3",)),
    ("10-singularities-and-switches.md", "ch10-det-agreement",
     "meets the bound (10.a)", ()),
    ("10-singularities-and-switches.md", "ch10-branch-limit",
     "far inside the theorem's bound", ()),
    ("10-singularities-and-switches.md", "ch10-change-point-limit",
     "All along the path, at each low minimum", ()),
    ("10-singularities-and-switches.md", "ch10-allowed-over-gap",
     "The admissible error shrinks with the gap", ()),
    ("10-singularities-and-switches.md", "ch10-sigma-max-over-l",
     "puts the theorem's $L$ in place of", ()),
    ("10-singularities-and-switches.md", "ch10-dead-angle-gap",
     "the crank rocks while the rod turns over and over", ()),
    ("10-singularities-and-switches.md", "ch10-rocking-residual",
     "The redundant formulations, `NullSpace` with either basis", ()),
    ("10-singularities-and-switches.md", "ch10-rocking-distance",
     "The redundant formulations, `NullSpace` with either basis", ()),
    ("10-singularities-and-switches.md", "ch10-naive-overshoot",
     "the budget of evaluations runs out at most", ()),
    ("10-singularities-and-switches.md", "ch10-event-evaluations",
     "The event-based run at the same tolerance needs only", ("200",)),
    ("10-singularities-and-switches.md", "ch10-sticking-time-spread",
     "Its sticking time and final crank angle agree across tolerances", ()),
    ("10-singularities-and-switches.md", "ch10-final-phi-spread",
     "Its sticking time and final crank angle agree across tolerances", ()),
    ("10-singularities-and-switches.md", "ch10-ramp-explicit-growth",
     "DOP853 takes at least", ()),
    ("10-singularities-and-switches.md", "ch10-sigma-max-first-smallest",
     "the smallest $\\sigma_{\\max}$ is", ()),
    ("10-singularities-and-switches.md", "ch10-sigma-max-first-L",
     "the smallest $\\sigma_{\\max}$ is", ()),
    ("10-singularities-and-switches.md", "ch10-sigma-max-last-smallest",
     "the smallest $\\sigma_{\\max}$ is", ()),
    ("10-singularities-and-switches.md", "ch10-sigma-max-last-L",
     "the smallest $\\sigma_{\\max}$ is", ()),
    ("11-energy.md", "ch11-gas-per-cycle",
     "compute the torque's work per crank turn and the gas force's work per slider cycle", ()),
    ("11-energy.md", "ch11-turn-cycle-gap",
     "exact work function the two agree to", ()),
    ("11-energy.md", "ch11-rotating-gain-low",
     "tightening the integrator shrinks the residual", ("2", "4")),
    ("11-energy.md", "ch11-rotating-gain-high",
     "tightening the integrator shrinks the residual", ("2", "4")),
    ("11-energy.md", "ch11-swinging-gain-low",
     "the same tightening shrinks the residual", ("1", "3")),
    ("11-energy.md", "ch11-swinging-gain-high",
     "the same tightening shrinks the residual", ("1", "3")),
    ("11-energy.md", "ch11-largest-ripple-per-turn",
     "Every turn of a rotating crank nearly balances", ("1",)),
    ("11-energy.md", "ch11-ripple-share",
     "The ripple's work is at most", ()),
    ("11-energy.md", "ch11-first-barrier",
     "the barrier after the first well rises", ()),
    ("11-energy.md", "ch11-largest-slope",
     "Wells exist because the largest slope of", ()),
    ("11-energy.md", "ch11-thousands-works-kj",
     "The two works are each a thousand times larger", ()),
    ("11-energy.md", "ch11-thousands-largest-slope",
     "The largest slope of $\\Pi$ is", ()),
    ("11-energy.md", "ch11-thousands-torque-over-slope",
     "The largest slope of $\\Pi$ is", ()),
    ("12-basins.md", "ch12-stuck-swings",
     "The slider has already stuck in", ()),
    ("12-basins.md", "ch12-swings",
     "The slider has already stuck in", ()),
    ("12-basins.md", "ch12-widest-swing-dphi0",
     "The widest swing starts with", ()),
    ("12-basins.md", "ch12-widest-swing-phi0",
     "The widest swing starts with", ()),
    ("12-basins.md", "ch12-widest-margin",
     "The widest swing starts with", ()),
    ("12-basins.md", "ch12-lowest-order",
     "The error falls at close to the fourth order of RK4", ("4",)),
    ("12-basins.md", "ch12-highest-order",
     "The error falls at close to the fourth order of RK4", ("4",)),
    ("12-basins.md", "ch12-margin-over-error",
     "At the step of the maps (grey line) the error is", ()),
    ("12-basins.md", "ch12-agreeing-cells",
     "The adaptive runs classify", ()),
    ("12-basins.md", "ch12-checked-cells",
     "The adaptive runs classify", ()),
    ("12-basins.md", "ch12-checked-on-boundary",
     "The adaptive runs classify", ()),
    ("12-basins.md", "ch12-map-step",
     "Why, then, can a fixed step of", ()),
    ("12-basins.md", "ch12-disagreeing-cells",
     "checked cells that disagree with the map is", ()),
    ("12-basins.md", "ch12-ex1-predicted",
     "energy barrier", ("7",)),
    ("12-basins.md", "ch12-ex1-bracket-minus-predicted",
     "the middle of the bracket found here", ("7",)),
    ("13-four-bar.md", "ch13-ex3-stopping-checks",
     "In these runs", ()),
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
    ("13-four-bar.md", "ch13-redundant-stop-gap",
     "redundant ones stop within", ()),
    ("13-four-bar.md", "ch13-rank-limit",
     "NullSpace meets it before its own test", ()),
    ("13-four-bar.md", "ch13-minimal-stop-early",
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
    ("08-error-vs-runtime.md", "ch08-library-best-words",
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
     "reference agrees with the tight solution to about", ("2", "10")),
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
    ("08-error-vs-runtime.md", "ch08-closed-form-gains",
     "the closed form runs with the gains", ()),
    ("08-error-vs-runtime.md", "ch08-orthogonal-gains",
     "the closed form runs with the gains", ()),
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
    ("08-error-vs-runtime.md", "ch08-cheapest-all-words",
     "The cheapest of all is", ()),
    ("08-error-vs-runtime.md", "ch08-cheapest-all-levels",
     "The cheapest of all is", ()),
    ("08-error-vs-runtime.md", "ch08-cheapest-book-words",
     "Among the book's own formulations with", ()),
    ("08-error-vs-runtime.md", "ch08-cheapest-book-levels",
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
    ("09-stiffness-and-long-runs.md", "ch09-message-step",
     "Here the test of this section decides", ()),
    ("09-stiffness-and-long-runs.md", "ch09-message-alpha-h",
     "Here the test of this section decides", ()),
    ("09-stiffness-and-long-runs.md", "ch09-continuation-phi-error",
     "its crank angle differs from the run at", ("0.6", "1")),
    ("09-stiffness-and-long-runs.md", "ch09-max-step-phi-error",
     "its crank angle differs from the run at", ("0.6", "1")),
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

@dataclass(frozen=True)
class Printed:
    """The numbers a chapter's code cells print that ``pattern``'s first group matches, times ``scale``."""

    pattern: str
    scale: float = 1.0


#: (chapter file, words of the sentence, left, relation, right): "left relation right" must hold
#: in the build's run of the chapter; see the module's docstring. Every number the prose pastes
#: right after a bound word is the right side of an entry (or in NOT_BOUNDS).
BOUNDS = [
    ("02-lagrange-multipliers.md", "Both exponents", "ch02-position-drift-exponent", ">", 1.5),
    ("02-lagrange-multipliers.md", "Both exponents", "ch02-position-drift-exponent", "<", 2.0),
    ("02-lagrange-multipliers.md", "Both exponents", "ch02-velocity-drift-exponent", ">", 0.5),
    ("02-lagrange-multipliers.md", "Both exponents", "ch02-velocity-drift-exponent", "<", 1.0),
    ("03-baumgarte.md", "a little less than linearly", "ch03-nfev-doubling", "<", 2.0),
    ("03-baumgarte.md", "In every row", Printed(r"^(?:Baumgarte|step rule).*\s(\d+\.\d\d)\s+\d+$"),
     "<=", "ch03-largest-alpha-h"),
    ("04-orthogonality.md", "both hold", Printed(r"^(?:orthogonal|baumgarte)\s+\d+\s+\S+\s+(\S+)", 1e9),
     "<=", "ch04-residual-over-tolerance"),
    ("04-orthogonality.md", "both stay within", Printed(r"^(?:orthogonal|baumgarte)\s+\d+\s+\S+\s+\S+\s+(\S+)", 1e9),
     "<=", "ch04-distance-over-tolerance"),
    ("04-orthogonality.md", "yet their power", Printed(r"max \|lambda\^T Phi_s s'\| = (\S+) W"),
     "<=", "ch04-largest-power"),
    ("04-orthogonality.md", "is well conditioned all the way round",
     Printed(r"cond\(Phi_z\) between \S+ and (\S+)$"), "<=", "ch04-largest-cond-phi-z"),
    ("06-four-cases.md", "swings up beyond the horizontal", "ch06-case1-excursion", ">", math.pi),
    ("06-four-cases.md", "swings up beyond the horizontal", "ch06-case1-excursion", "<", "ch06-three-quarter-turn"),
    ("06-four-cases.md", "Starting with the potential energy of the top",
     Printed(r"^case 2: .*\n.*\n.*\n  phi' between (\S+) and"), ">=", "ch06-case2-slowest"),
    ("06-four-cases.md", "the speed dips on every",
     Printed(r"^case 4: .*\n.*\n.*\n  phi' between (\S+) and"), ">=", "ch06-case4-slowest"),
    ("06-four-cases.md", "In all four runs", Printed(r"max \|f\| = (\S+) m"), "<=", "ch06-largest-residual"),
    ("06-four-cases.md", "The two matches of `thousands-opposing` are hollow",
     Printed(r"sticks\xa0at\xa0\S+-(\d+\.\d+)\xa0s"), "<=", "ch06-thousands-stuck-by"),
    ("06-four-cases.md", "With thousands it does so beside a huge torque",
     Printed(r"runs\xa0away\xa0at\xa0\S+-(\d+\.\d+)\xa0s"), "<=", "ch06-printed-runaway-by"),
    ("06-four-cases.md", "Read as decimals, that deficit", Printed(r"gravity: Pi between -(\S+) and"),
     "<=", "ch06-gravity-amplitude"),
    ("06-four-cases.md", "Read as decimals, that deficit", Printed(r"gravity: Pi between \S+ and (\S+) J"),
     "<=", "ch06-gravity-amplitude"),
    ("06-four-cases.md", "Case 1 brings more", Printed(r"case 1: initial kinetic energy T = (\S+) J"),
     ">", "ch06-deficit"),
    ("06-four-cases.md", "Case 1 brings more", Printed(r"case 3: initial kinetic energy T = (\S+) J"),
     "<", "ch06-deficit"),
    ("06-four-cases.md", "in case 3 only just", "ch06-case3-torque-push", ">", 0.0),
    ("06-four-cases.md", "the bar stands at", "ch06-largest-kinetic", ">", "ch06-top-bar"),
    ("06-four-cases.md", "the bar stands at", "ch06-case1-kinetic", "<", "ch06-top-bar"),
    ("07-conclusions.md", "Notice: the balance (7.b) holds to", Printed(r"^\s+\d\s+\S+\s+\S+\s+\S+\s+(\d\.\d+e[-+]\d+)\s+(?:osc|full)"),
     "<=", "ch07-largest-balance-residual"),
    ("07-conclusions.md", "This neglects only the torque ripple",
     Printed(r"at most 2 pi \* \S+ = (\S+) J per turn"), "<=", "ch07-ripple-per-turn"),
    ("07-conclusions.md", "The torque per turn and the gas per stroke agree to within",
     Printed(r"torque per turn - gas per stroke: [+-]?(\S+) J"), "<=", "ch07-turn-stroke-gap"),
    ("09-stiffness-and-long-runs.md", "just inside the edge", "ch09-rk45-loosest-alpha-h", "<", "ch09-rk45-edge"),
    ("09-stiffness-and-long-runs.md", "The rule lies inside the stable region",
     "ch09-rule-margin-exact", "<=", "ch09-rule-margin"),
    ("10-singularities-and-switches.md", "meets the bound (10.a)",
     "ch10-det-agreement-exact", "<=", "ch10-det-agreement"),
    ("10-singularities-and-switches.md", "the crank rocks while the rod turns over and over",
     "ch10-dead-angle-gap-exact", "<=", "ch10-dead-angle-gap"),
    ("10-singularities-and-switches.md", "The redundant formulations, `NullSpace` with either basis",
     "ch10-rocking-residual-exact", "<=", "ch10-rocking-residual"),
    ("10-singularities-and-switches.md", "The redundant formulations, `NullSpace` with either basis",
     "ch10-rocking-distance-exact", "<=", "ch10-rocking-distance"),
    ("10-singularities-and-switches.md", "the budget of evaluations runs out at most",
     "ch10-naive-overshoot-exact", "<=", "ch10-naive-overshoot"),
    ("10-singularities-and-switches.md", "Its sticking time and final crank angle agree across tolerances",
     "ch10-sticking-time-spread-exact", "<=", "ch10-sticking-time-spread"),
    ("10-singularities-and-switches.md", "Its sticking time and final crank angle agree across tolerances",
     "ch10-final-phi-spread-exact", "<=", "ch10-final-phi-spread"),
    ("10-singularities-and-switches.md", "DOP853 takes at least",
     "ch10-ramp-explicit-growth-exact", ">=", "ch10-ramp-explicit-growth"),
    ("11-energy.md", "exact work function the two agree to",
     "ch11-turn-cycle-gap-exact", "<=", "ch11-turn-cycle-gap"),
    ("11-energy.md", "Every turn of a rotating crank nearly balances",
     "ch11-largest-ripple-per-turn-exact", "<=", "ch11-largest-ripple-per-turn"),
    ("11-energy.md", "The ripple's work is at most", "ch11-ripple-share-exact", "<=", "ch11-ripple-share"),
    ("12-basins.md", "At the step of the maps (grey line) the error is more than",
     "ch12-margin-over-error-exact", ">", "ch12-margin-over-error"),
    ("13-four-bar.md", "The five redundant ones stop within",
     "ch13-redundant-stop-gap-exact", "<=", "ch13-redundant-stop-gap"),
    ("13-four-bar.md", "short of the change point every formulation agrees",
     "ch13-largest-pendulum-error-exact", "<=", "ch13-largest-pendulum-error"),
    ("13-four-bar.md", "short of the change point every formulation agrees",
     "ch13-largest-energy-drift-exact", "<=", "ch13-largest-energy-drift"),
    ("13-four-bar.md", "the null-space formulation turns the crank back",
     "ch13-turning-vs-limit-exact", "<=", "ch13-turning-vs-limit"),
]

#: Numbers pasted after a bound word that state no bound on a result, each with the reason.
NOT_BOUNDS = {
    ("06-four-cases.md", "ch06-case1-excursion"): "the swing's reach itself ('to X rad from its start'), "
                                                   "bounded by the entries above",
    ("09-stiffness-and-long-runs.md", "ch09-augmented-drift"): "the drift the run ends with ('keeps growing, to X m')",
    ("12-basins.md", "ch12-widest-margin"): "the widest swing's reach ('to X rad short of a whole turn')",
    ("13-four-bar.md", "ch13-rank-limit"): "the library's rank test itself ('sigma_min below X times "
                                          "sigma_max'), an input, not a result",
}

_RELATIONS = {"<": operator.lt, "<=": operator.le, ">": operator.gt, ">=": operator.ge}
#: A glued value in prose, with its format spec.
_ROLE = re.compile(r"\{glue(?::text)?\}`([^`:]+)(?::([^`]*))?`")
#: Words right before a pasted value that make it a bound: "below X", "at most X", "(to X m)",
#: "agrees ... to X", "keeps ... to X", "X ... or more".
_BEFORE = re.compile(r"(?:\b(?:below|above|beyond|at most|at least|within|holds? to|up to|under|over|more than"
                     r"|less than|fewer than|exceeds?|limit to)|[(,]\s*to"
                     r"|\b(?:agrees?|keeps?)\b[^.;:]{0,80}?\bto)\s*$", re.I)
_AFTER = re.compile(r"^[^.;:]{0,40}?\bor (?:more|less|better)\b", re.I)
#: A value that continues a bound: "to X s and Y rad", "at most X m, Y".
_CONTINUED = re.compile(r"^\s*[^\s.;:]{0,8}\s*(?:and|,)\s*$")

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


def stated_bounds(sentence):
    """The glue keys that a sentence pastes as bounds: after a bound word, before "or more", or
    continuing a bound ("to X s and Y rad")."""
    previous_end, previous_bound = None, False
    for match in _ROLE.finditer(sentence):
        bound = bool(_BEFORE.search(sentence[:match.start()]) or _AFTER.search(sentence[match.end():])
                     or (previous_bound and _CONTINUED.match(sentence[previous_end:match.start()])))
        if bound:
            yield match.group(1)
        previous_end, previous_bound = match.end(), bound


def unlisted_bounds(chapter, markdown, bounds=None, not_bounds=None):
    """``(key, sentence)`` of each bound the prose states that no entry checks: the key is not the
    right side of an entry of `BOUNDS` for the chapter, nor in `NOT_BOUNDS`."""
    bounds, not_bounds = BOUNDS if bounds is None else bounds, NOT_BOUNDS if not_bounds is None else not_bounds
    listed = {right for file, _, _, _, right in bounds if file == chapter and isinstance(right, str)}
    return [(key, sentence) for sentence in sentences(markdown) for key in stated_bounds(sentence)
            if key not in listed and (chapter, key) not in not_bounds]


@functools.lru_cache(maxsize=None)
def glued_values(chapter, site):
    """``key -> value`` of every ``glue`` in the build's run of a chapter's current source (its execution
    cache), and the run's notebook."""
    import ast

    import jupytext
    import numpy
    from jupyter_cache import get_cache

    try:
        _, notebook = get_cache(site.parent / ".jupyter_cache").merge_match_into_notebook(
            jupytext.read(ROOT / "chapters" / chapter))
    except KeyError:
        pytest.fail(f"{chapter}: the build's execution cache holds no run of this page's current source")
    values = {}
    for cell in notebook.cells:
        for output in cell.get("outputs", []):
            record = output.get("metadata", {}).get("scrapbook")
            if record:
                text = output["data"][record["mime_prefix"] + "text/plain"]
                try:
                    values[record["name"]] = ast.literal_eval(text)
                except (ValueError, SyntaxError):
                    values[record["name"]] = eval(text, {"np": numpy})       # np.float64(...): the run's own output
    return values, notebook


def printed(notebook):
    """Every text the run's code cells print: streams, plain-text and Markdown results."""
    for cell in notebook.cells:
        for output in cell.get("outputs", []):
            if output.get("output_type") == "stream":
                yield output["text"]
            for mime in ("text/plain", "text/markdown"):
                if mime in output.get("data", {}) and "scrapbook" not in output.get("metadata", {}):
                    yield "".join(output["data"][mime])


def as_printed(markdown, key, value):
    """``value`` as the chapter's prose prints the glued ``key``, read back: one number per format spec
    the prose pastes it with (none if the prose does not paste it)."""
    specs = {spec for source in markdown for spec in re.findall(
        r"\{glue(?::text)?\}`" + re.escape(key) + r"(?::([^`]*))?`", source)}
    numbers = []
    for spec in sorted(specs):
        text = format(value, spec) if spec else str(value)
        numbers.append(float(text.rstrip("%")) / 100 if text.endswith("%") else float(text))
    return numbers


def side(value, values, notebook, markdown, left):
    """The numbers one side of a bound stands for (see the module's docstring)."""
    if isinstance(value, Printed):
        found = [float(number) * value.scale for text in printed(notebook)
                 for number in re.findall(value.pattern, text, re.M)]
        assert found, f"no printed output matches {value.pattern!r}"
        return found
    if isinstance(value, str):
        assert value in values, f"no cell of the run glues {value!r}"
        shown = as_printed(markdown, value, values[value])
        if left:
            return [values[value], *shown]            # the exact value, and as the prose shows it
        assert shown, f"the prose does not paste {value}, the bound"
        return shown
    return [float(value)]


@pytest.mark.parametrize("chapter, words, left, relation, right", BOUNDS,
                         ids=[f"{b[0][:2]}-{b[2] if isinstance(b[2], str) else 'printed'}{b[3]}{b[4]}"
                              for b in BOUNDS])
def test_a_stated_bound_holds_for_the_values_it_bounds(chapter, words, left, relation, right, built_site):
    """"|f| never exceeds 4.5e-09 m" above runs that print 4.4e-09: checked on the build's own run."""
    markdown, _ = markdown_and_code(chapter)
    sentence_with(markdown, words)                 # the sentence that states it is still there
    values, notebook = glued_values(chapter, built_site)
    bounds = side(right, values, notebook, markdown, left=False)
    numbers = side(left, values, notebook, markdown, left=True)
    broken = [(value, bound) for value in numbers for bound in bounds if not _RELATIONS[relation](value, bound)]
    assert not broken, (f"{chapter}: '{words}' states {left} {relation} {right}, but (value, bound as printed) "
                        f"{broken}: glue the bound with closedloop.plotting.rounded_bound (up for an upper "
                        f"bound, down for a lower one) at the digits the prose prints")


@pytest.mark.parametrize("chapter", sorted(path.name for path in (ROOT / "chapters").glob("*.md")))
def test_every_stated_bound_is_checked(chapter):
    """A number pasted after "below", "at most", "within", "(to", "agrees ... to", ... or before "or
    more" is the right side of an entry of BOUNDS (or a listed NOT_BOUNDS, with its reason)."""
    markdown, _ = markdown_and_code(chapter)
    missing = unlisted_bounds(chapter, markdown)
    assert not missing, f"{chapter}: bounds stated in prose but not in BOUNDS: {missing}"


def test_every_exact_value_is_a_side_of_a_bound():
    """A hidden ``...-exact`` glue exists only to check a bound: one that no entry uses checks nothing;
    and an entry of NOT_BOUNDS names a number the prose still pastes after a bound word."""
    used = {(chapter, key) for chapter, _, left, _, right in BOUNDS for key in (left, right) if isinstance(key, str)}
    for path in sorted((ROOT / "chapters").glob("*.md")):
        markdown, code = markdown_and_code(path.name)
        for key in re.findall(r"\bglue\(\s*[\"']([^\"']+-exact)[\"']", "\n".join(code)):
            assert (path.name, key) in used, f"{path.name} glues {key}, which no entry of BOUNDS uses"
    for chapter, key in NOT_BOUNDS:
        assert any(key in stated_bounds(sentence) for sentence in sentences(markdown_and_code(chapter)[0])), \
            f"{chapter}: NOT_BOUNDS lists {key}, which no sentence pastes after a bound word any more"


def test_the_bound_checks_see_a_broken_bound():
    """A bound rounded to nearest fails where the same bound from `rounded_bound` passes, on either side:
    "at most 2.3" of 2.349, "below 2e-10" of 2.4e-10, "more than 7 orders" of 6.6, "40 or more" of 39.7,
    "at most 34 %" of 0.3449."""
    from closedloop.plotting import rounded_bound

    for exact, spec, relation in ((2.349, ".1f", "<="), (2.4e-10, ".0e", "<="), (6.6, "d", ">"),
                                  (39.7, ".0f", ">="), (0.3449, ".0%", "<=")):
        markdown = (f"It is {{glue:text}}`k:{spec}`.",)
        upper = relation.startswith("<")
        nearest = round(exact) if spec == "d" else exact
        safe = int(rounded_bound(exact, ".0f", upper)) if spec == "d" else rounded_bound(exact, spec, upper)
        test = _RELATIONS[relation]
        assert not test(exact, *as_printed(markdown, "k", nearest)), (exact, spec, as_printed(markdown, "k", nearest))
        assert test(exact, *as_printed(markdown, "k", safe)), (exact, spec, as_printed(markdown, "k", safe))
    assert as_printed(("{glue:text}`k:.1f` and {glue:text}`k:.3f`",), "k", 2.3456) == [2.3, 2.346]   # every spec
    assert as_printed(("{glue:text}`k:.0%`",), "k", 0.504) == [0.5]


def test_the_words_that_state_a_bound_are_found():
    assert list(stated_bounds("Both runs hold |f| below {glue:text}`a:.1f` times the tolerance.")) == ["a"]
    assert list(stated_bounds("a step more than {glue:text}`k:.2f` times as long")) == ["k"]
    assert list(stated_bounds("It takes {glue:text}`k:.0f` times 1/alpha or more.")) == ["k"]
    assert list(stated_bounds("It takes {glue:text}`k:.0f` times as long.")) == []
    assert list(stated_bounds("The ratios run from {glue:text}`a:.1f` to {glue:text}`b:.1f`.")) == []
    assert list(stated_bounds("They agree across tolerances, to {glue:text}`a:.0e` s and {glue:text}`b:.0e` "
                              "rad, after {glue:text}`c:d` steps.")) == ["a", "b"]
    assert list(stated_bounds("It meets the bound (to {glue:text}`a:.0e` m for every rod).")) == ["a"]
    assert list(stated_bounds("It keeps $T$ to {glue:text}`a:.0e` J.")) == ["a"]


def test_an_unchecked_bound_is_found():
    """The list check fails on a bound that no entry checks, and passes once an entry does."""
    markdown = ("Notice: $|f|$ stays at most {glue:text}`ch99-f:.1e` m and within {glue:text}`ch99-g:.0e` "
                "of the reference, over {glue:text}`ch99-n:d` runs that take {glue:text}`ch99-t:.1f` s.",)
    assert [key for key, _ in unlisted_bounds("99.md", markdown, [], {})] == ["ch99-f", "ch99-g", "ch99-n"]
    entries = [("99.md", "Notice", "ch99-f-exact", "<=", "ch99-f"), ("99.md", "Notice", "ch99-g-exact", "<=", "ch99-g")]
    assert unlisted_bounds("99.md", markdown, entries, {("99.md", "ch99-n"): "a count"}) == []


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
