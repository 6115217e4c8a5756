"""Every exercise check answers any value a student may type: right, not right yet, or the wrong kind.

Never a traceback, never a wrong kind of answer taken for a right one ("1" or True for 1), and an
answer of the wrong kind (text for a number, None, NaN) is told so instead of "not right yet".
"""

import importlib
import math
import sys
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

EXERCISES = Path(__file__).resolve().parents[1] / "exercises"
sys.path.insert(0, str(EXERCISES))
checking = importlib.import_module("checking")
CHAPTERS = sorted(path.stem for path in (EXERCISES / "checking").glob("ch[0-9][0-9].py"))
CHECKS = [check for chapter in CHAPTERS for check in importlib.import_module(f"checking.{chapter}").CHECKS.values()]

ANYTHING = st.one_of(st.none(), st.booleans(), st.text(max_size=6), st.integers(-10**6, 10**6),
                     st.floats(allow_nan=True, allow_infinity=True), st.lists(st.floats(), max_size=4),
                     st.tuples(st.integers(), st.text(max_size=2)), st.dictionaries(st.text(max_size=2),
                                                                                   st.integers(), max_size=2))


def verdict(check, answer, capsys):
    right = check(answer)
    lines = capsys.readouterr().out.splitlines()
    assert isinstance(right, bool)
    assert len(lines) == 1 and lines[0].startswith(f"Exercise {check.label}: ")
    return right, lines[0]


@pytest.mark.parametrize("check", CHECKS, ids=lambda check: check.label)
@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(answer=ANYTHING)
def test_any_answer_gets_one_line_and_no_traceback(check, answer, capsys):
    right, _ = verdict(check, answer, capsys)
    if right:                                        # only a value equal to the expected one may pass
        assert not isinstance(answer, (str, bool)) or check.compare is checking.choice


@pytest.mark.parametrize("label", ["1.5", "13.4"])      # checking.same_angles: one angle of two, and all
def test_an_angle_check_takes_finite_numbers_only_and_warns_of_nothing(label, capsys, recwarn):
    # found by the test above: an infinite angle in 13.4 gave NaN cosines and a RuntimeWarning beside the
    # verdict; [True, True] passed both checks' comparison as numbers (their comparators then bypassed
    # checking.as_numbers)
    check = next(check for check in CHECKS if check.label == label)
    size = np.size(check.expected_value())
    for answer in ([math.inf] * size, [math.nan] * size, True, [True] * size, [1.0] * (size + 1)):
        right, line = verdict(check, answer, capsys)
        assert not right and "expected" in line and "not right yet" not in line, (answer, line)
    assert [str(warning.message) for warning in recwarn] == []
    turned = np.asarray(check.expected_value(), dtype=float) + 2 * math.pi * (np.arange(size) == 0)
    assert verdict(check, list(turned), capsys)[0]                          # the first angle is taken modulo 2 pi


@pytest.mark.parametrize("label, answers", [
    ("7.9", ["1e-8", True, math.inf, math.nan, [1e-8]]),                           # ch07._same_decade
    ("3.5", [["-1+2j", "-1-2j"], [True, True], [math.inf, 1.0], [1.0, 2.0, 3.0]]),  # ch03.same_roots
    ("10.5", ["abc", "l1", True, None]),                                   # ch10.same_function_of_lengths
])
def test_the_comparators_of_their_own_refuse_text_bools_and_non_finite_numbers(label, answers, capsys):
    # a text "1e-8" was read as the number by 7.9's own comparator, and could be marked right; 3.5's parsed
    # text as complex numbers: both now take the answer through checking.as_numbers, as numeric() does;
    # 10.5's took "abc" for a symbol (now refused as symbolic() refuses it: checking.not_an_expression)
    check = next(check for check in CHECKS if check.label == label)
    for answer in answers:
        right, line = verdict(check, answer, capsys)
        assert not right and "expected" in line and "not right yet" not in line, (answer, line)


NUMERIC = [check for check in CHECKS if np.ndim(check.expected_value()) == 0
           and isinstance(check.expected_value(), (int, float, np.number)) and check.compare is not checking.choice]


@pytest.mark.parametrize("check", NUMERIC[:6], ids=lambda check: check.label)
@pytest.mark.parametrize("answer", [None, "1", True, [1.0, 2.0], math.nan, "abc"],
                         ids=["None", "text 1", "True", "list", "NaN", "text"])
def test_a_number_check_tells_the_wrong_kind(check, answer, capsys):
    right, line = verdict(check, answer, capsys)
    assert not right
    assert "expected" in line and "not right yet" not in line


def test_text_and_true_are_not_one():
    check = checking.Check("x.1", lambda: 1, checking.numeric(0, 0), "hint", lambda e: e + 1)
    assert check(1) and check(np.int64(1)) and check(1.0)
    assert not check("1") and not check(True) and not check(np.bool_(True))


def test_a_failure_of_the_expected_value_is_the_books_error_not_a_wrong_answer():
    def broken():
        raise ZeroDivisionError("the book's own bug")

    check = checking.Check("x.2", broken, checking.numeric(), "hint", lambda e: e + 1)
    with pytest.raises(ZeroDivisionError):
        check(1.0)


SYMBOLIC = [check for check in CHECKS if getattr(check.compare, "__qualname__", "").startswith("symbolic.")]


@pytest.mark.parametrize("check", SYMBOLIC[:4], ids=lambda check: check.label)
@pytest.mark.parametrize("answer", [[None], [{"a": 1}], {1, 2}], ids=["None in a list", "dict in a list", "set"])
def test_a_symbolic_check_tells_the_wrong_kind_of_entries_without_a_warning(check, answer, capsys, recwarn):
    # Entries that are not expressions: sympy's Matrix would take them with a deprecation warning (and
    # the check would say "not right yet"); the student is told what kind of answer is expected instead.
    right, line = verdict(check, answer, capsys)
    assert not right
    assert "expected a sympy expression or matrix" in line
    assert not [w for w in recwarn if "deprecated" in str(w.message).lower()]


def _compare(label, answer):
    """The verdict of the check ``label`` on ``answer``, without its printed line."""
    check = next(check for check in CHECKS if check.label == label)
    return bool(check.compare(answer, check.expected_value()))


def test_plausible_slips_are_not_taken_for_right_answers():
    """Slips a review found the checks let through, each computed as a student would make it, against
    the right answer computed the page's own way (exercises 2.7, 3.6, 9.6 and 11.5)."""
    from closedloop import Augmented, Baumgarte, baumgarte_p2, simulate
    from closedloop.slider_crank import CASES, OMEGA, initial_state, slider_crank_system
    from closedloop.studies.energy import gas_outward_work

    ch03, ch09, ch11 = (importlib.import_module(f"checking.{name}") for name in ("ch03", "ch09", "ch11"))
    system = slider_crank_system()

    # 2.7: case 1's drift for case 4's (1.7 % apart)
    def drift(number):
        case = CASES[number]
        return simulate(system, initial_state(system, case.phi0, case.dphi0), 20.0, formulation=Augmented(),
                        method="RK45", rtol=1e-6, atol=1e-6).max_constraint_error
    assert _compare("2.7", drift(4)) and not _compare("2.7", drift(1))

    # 3.6: alpha and beta swapped (with f' = 5 f, (2, 8) and (8, 2) gave the same p2~)
    state = initial_state(system, 2.0, 1.5)
    s, sd = state.s + np.array([0.0, 0.0, 2e-3]), state.sd + np.array([0.0, 0.0, 1e-2])
    _, _, f, Phi, gamma = system.dynamics(0.0, s, sd)
    alpha, beta = ch03.P2_GAINS
    assert _compare("3.6", baumgarte_p2(Phi, gamma, f, sd, alpha, beta))
    assert not _compare("3.6", baumgarte_p2(Phi, gamma, f, sd, beta, alpha))

    # 9.6: the work of the mean torque only, the ripple's left out (the trapezoidal rule, as the page)
    case = CASES[2]
    run = simulate(system, initial_state(system, case.phi0, case.dphi0), ch09.WORK_END,
                   formulation=Baumgarte(5, 5), method="DOP853", rtol=1e-10, atol=1e-10,
                   t_eval=ch09.WORK_TIMES, work=True)
    ripple = 0.01 * np.sin(OMEGA * run.t) * run.velocity("phi")
    ripple_work = float(np.sum(0.5 * (ripple[1:] + ripple[:-1]) * np.diff(run.t)))
    right = run.work[-1] - run.work[0]
    assert _compare("9.6", right) and not _compare("9.6", right - ripple_work)

    # 11.5: the turning points left out (the intervals outward at both ends, or at their start only)
    result = ch11._run(3)
    x, rate = result.coordinate("x"), result.velocity("x")
    steps = np.diff(gas_outward_work(x))
    assert not _compare("11.5", float(np.sum(steps[(rate[:-1] > 0) & (rate[1:] > 0)])))
    assert not _compare("11.5", float(np.sum(steps[rate[:-1] > 0])))


LABELS = st.one_of(st.none(), st.booleans(), st.integers(-100, 100), st.floats(allow_nan=True),
                   st.text(max_size=6), st.lists(st.text(max_size=3), max_size=2), st.tuples(st.integers()),
                   st.dictionaries(st.text(max_size=2), st.integers(), max_size=1))


@settings(max_examples=60, deadline=None)
@given(label=LABELS)
def test_a_label_of_any_kind_gets_one_plain_line(label):
    """check(3.5, x) raised a raw KeyError (its message in quotes), check(["3.5"], x) a TypeError (unhashable):
    every label that is no exercise of the chapter is refused with one plain line that says what a label is."""
    ch03 = importlib.import_module("checking.ch03")
    if isinstance(label, str) and label in ch03.CHECKS:
        return
    with pytest.raises(checking.UnknownExercise) as error:
        ch03.check(label, 1.0)
    message = str(error.value)
    assert "\n" not in message and not message.startswith(("'", '"'))
    if isinstance(label, str):
        assert message == f"no exercise {label!r} here; the exercises are 3.5, 3.6, 3.7, 3.8, 3.9"
    else:
        assert message.startswith("check(label, answer): the label is the exercise's number in quotes, such as "
                                  f"'3.5', got {label!r} ({type(label).__name__})")


def test_the_label_as_advised_gets_a_verdict(capsys):
    ch03 = importlib.import_module("checking.ch03")
    with pytest.raises(checking.UnknownExercise):
        ch03.check(3.5, 1.0)
    ch03.check("3.5", 1.0)                                  # the label in quotes, as the message says
    assert capsys.readouterr().out.startswith("Exercise 3.5: ")


@pytest.mark.parametrize("answer, line", [
    (math.inf, "expected a finite number, got inf"),
    ([1.0, math.nan], "expected finite numbers in an array of shape (2,), got [1.0, nan]"),
    (1 + 2j, "expected a number, got a complex number"),
    ([1j, 2.0], "expected numbers in an array of shape (2,), got complex numbers"),
])
def test_a_wrong_kind_of_number_is_said_in_words_without_a_warning(answer, line, capsys, recwarn):
    """It said "expected finite a number", and a complex answer printed numpy's ComplexWarning first."""
    expected = 2.0 if np.ndim(answer) == 0 else np.array([1.0, 2.0])
    check = checking.Check("x.3", lambda: expected, checking.numeric(), "hint", lambda e: e + 1)
    assert not check(answer)
    assert capsys.readouterr().out == f"Exercise x.3: {line}.\n"
    assert [str(warning.message) for warning in recwarn] == []
