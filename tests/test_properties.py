"""Property-based tests of input handling: any value gives a correct result or the library's own error.

hypothesis throws generated values (floats with NaN, infinities, huge and tiny ones, integers beyond
float's range, numpy scalars, fractions, decimals, complex numbers, strings, None, booleans,
containers, objects) at the validators of SliderCrankParameters, initial_state, System (the
slider-crank and the four-bar), simulate and the command line.  Every outcome must be

- a correct result: a valid object, a consistent state, a run with finite t, s and s';
- or a ClosedLoopError (InputError for bad input) whose message is one line and names the parameter;

never another exception, a RuntimeWarning, a NaN, or a hang (an example running longer than
HANG_SECONDS fails).  check() of the exercises is covered in test_answer_checks.py.
benchmarks/fuzz_inputs.py draws the same families with numpy's Generator and counts the outcomes.
"""

import contextlib
import json
import math
import re
import signal
import warnings
from fractions import Fraction

import numpy as np
import pytest
import scipy.integrate
from hypothesis import HealthCheck, currently_in_test_context, event, example, given, settings
from hypothesis import strategies as st

import closedloop
from closedloop import ClosedLoopError, InputError, System
from closedloop import four_bar, slider_crank
from closedloop.cli import main
from closedloop.formulations import FORMULATION_NAMES, formulation_from_name
from closedloop.methods import SOLVER_METHODS

#: An example that runs longer than this is a hang.
HANG_SECONDS = 30.0


class Hang(BaseException):
    """Raised in the example by the alarm after HANG_SECONDS."""


def _alarm(signum, frame):
    raise Hang


@contextlib.contextmanager
def no_hang_and_no_runtime_warning():
    """Fail if the block runs longer than HANG_SECONDS or emits a RuntimeWarning."""
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, HANG_SECONDS)
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                yield
            except Hang:
                pytest.fail(f"still running after {HANG_SECONDS:g} s")
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)
    runtime = [str(w.message) for w in caught if issubclass(w.category, RuntimeWarning)]
    assert not runtime, f"RuntimeWarning escaped: {runtime}"


def count(kind):
    """Note an outcome for ``pytest --hypothesis-show-statistics`` (inside a hypothesis test)."""
    if currently_in_test_context():
        event(kind)


def outcome(function, *args, **kwargs):
    """``(result, None)`` or ``(None, error)`` for a ClosedLoopError; any other exception fails the test."""
    with no_hang_and_no_runtime_warning():
        try:
            result = function(*args, **kwargs)
        except ClosedLoopError as error:
            count(f"outcome: {type(error).__name__}")
            return None, error
    count("outcome: result")
    return result, None


def assert_one_line(error, *names):
    """The error's message is one non-empty line (starting with one of ``names``, if given)."""
    text = str(error)
    assert text and "\n" not in text and "\r" not in text, f"not one line: {text!r}"
    if names:
        assert text.startswith(names), f"names none of {names}: {text!r}"


def finite(*arrays):
    return all(np.all(np.isfinite(np.asarray(a, dtype=float))) for a in arrays)


# -- families of values ---------------------------------------------------------------------------

NUMPY_SCALARS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True).map(np.float64),
    st.floats(width=32, allow_nan=True, allow_infinity=True).map(np.float32),
    st.floats(width=16, allow_nan=True, allow_infinity=True).map(np.float16),
    st.integers(-2**63, 2**63 - 1).map(np.int64),
    st.integers(0, 255).map(np.uint8),
    st.floats(allow_nan=False, allow_infinity=False).map(np.longdouble),
)
ANY_NUMBER = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([math.nan, math.inf, -math.inf, 0.0, -0.0, 5e-324, 1e-300, 1e300, 1.7976931348623157e308]),
    st.integers(),
    st.sampled_from([10**400, -(10**400), 2**1024]),       # 10**5000: below (hypothesis cannot repr it)
    st.fractions(),
    st.sampled_from([Fraction(10**400, 3), Fraction(1, 10**400)]),
    NUMPY_SCALARS,
)
NO_NUMBER = st.one_of(
    st.none(), st.booleans(), st.just(np.bool_(True)), st.text(max_size=5), st.binary(max_size=3),
    st.complex_numbers(allow_nan=True), st.decimals(allow_nan=True), st.lists(st.floats(), max_size=3),
    st.tuples(st.floats()), st.dictionaries(st.text(max_size=2), st.integers(), max_size=2),
    st.sampled_from([np.array([1.0, 2.0]), np.array(1.0), np.array([]), np.eye(3), object(), float, "1\n2"]),
)


def near(typical):
    """Plausible values: within a factor of 10 of ``typical`` (0 to 1 for a typical 0)."""
    low, high = (typical / 10, typical * 10) if typical else (0.0, 1.0)
    return st.one_of(st.floats(low, high), st.floats(low, high).map(np.float64),
                     st.integers(max(1, int(low)), max(1, int(high))))


def values(typical):
    return st.one_of(near(typical), ANY_NUMBER, NO_NUMBER)


# -- SliderCrankParameters ------------------------------------------------------------------------

TABLE_1 = slider_crank.SliderCrankParameters()
FIELDS = {name: value for name, value in TABLE_1.as_dict().items()}
FIELD_NAMES = tuple(f"{name}:" for name in FIELDS) + ("full_rotation:",)


@st.composite
def parameter_fields(draw):
    names = draw(st.lists(st.sampled_from(sorted(FIELDS)), unique=True, max_size=4))
    fields = {name: draw(values(FIELDS[name])) for name in names}
    if draw(st.booleans()):
        fields["full_rotation"] = draw(st.one_of(st.booleans(), st.sampled_from([np.bool_(False), 0, 1, "yes"]),
                                                 st.none()))
    return fields


@settings(max_examples=500, deadline=None)
@given(fields=parameter_fields())
@example(fields={"l1": 10**400})
@example(fields={"m1": Fraction(10**400, 3)})
@example(fields={"l1": Fraction(4), "l2": Fraction(3)})
@example(fields={"a2": Fraction(9)})
def test_slider_crank_parameters(fields):
    check_parameters(fields)


@pytest.mark.parametrize("name", ["l1", "m1", "g", "full_rotation"])
@pytest.mark.parametrize("value", [10**5000, Fraction(10**5000, 3), -(10**5000)], ids=["int", "Fraction", "negative"])
def test_numbers_beyond_the_digits_python_prints(name, value):
    check_parameters({name: value})              # repr() of them raises ValueError (Python's 4300 digits)


def check_parameters(fields):
    made, error = outcome(slider_crank.SliderCrankParameters, **fields)
    if error is not None:
        assert isinstance(error, InputError)
        assert_one_line(error, *FIELD_NAMES)
        return
    numbers = [float(v) for v in made.as_dict().values()]
    assert finite(numbers)
    assert (float(made.l1) < float(made.l2)) == made.full_rotation
    assert 0.0 <= float(made.a2) <= float(made.l2)


# -- initial_state ------------------------------------------------------------------------------

SYSTEM = slider_crank.slider_crank_system()
ROCKING = slider_crank.slider_crank_system(
    slider_crank.SliderCrankParameters(l1=3.5, l2=2.0, a2=1.0, full_rotation=False))
ANGLES = st.one_of(st.floats(-1e3, 1e3), st.sampled_from([math.pi, math.pi / 2, math.asin(2 / 3.5), 1e3,
                                                          np.nextafter(1e3, 2e3)]), ANY_NUMBER, NO_NUMBER)
SPEEDS = st.one_of(st.floats(-1e3, 1e3), ANY_NUMBER, NO_NUMBER)


def check_initial_state(system, phi0, dphi0):
    state, error = outcome(slider_crank.initial_state, system, phi0, dphi0)
    if error is not None:
        if isinstance(error, InputError):
            assert_one_line(error, "phi0:", "dphi0:")
        else:                                       # a dead position of the rocking crank
            assert_one_line(error)
        return
    assert finite(state.s, state.sd)
    scale = 1.0 + np.max(np.abs(state.s))
    assert np.max(np.abs(system.constraints(state.s))) <= 1e-9 * scale
    assert np.max(np.abs(system.jacobian(state.s) @ state.sd)) <= 1e-9 * (1.0 + np.max(np.abs(state.sd)))


@settings(max_examples=300, deadline=None)
@given(phi0=ANGLES, dphi0=SPEEDS)
@example(phi0=10**400, dphi0=1.0)
def test_initial_state(phi0, dphi0):
    check_initial_state(SYSTEM, phi0, dphi0)


@settings(max_examples=150, deadline=None)
@given(phi0=ANGLES, dphi0=SPEEDS)
def test_initial_state_of_a_rocking_crank(phi0, dphi0):
    check_initial_state(ROCKING, phi0, dphi0)


# -- System ---------------------------------------------------------------------------------------

SLIDER_CRANK_VALUES = four_bar.parameter_values(SYSTEM)
FOUR_BAR_VALUES = {"l0": 4.0, "l1": 1.0, "l2": 3.5, "l3": 3.0, "m1": 1.0, "m2": 3.0, "m3": 2.5, "g": 9.81}
MODELS = {"slider-crank": (slider_crank.slider_crank_model(), SLIDER_CRANK_VALUES),
          "four-bar": (four_bar.four_bar_model(), FOUR_BAR_VALUES)}
NO_MAPPING = st.sampled_from([None, [], [1.0, 2.0], "l1", 5, np.array([1.0, 2.0]), object(), [("l1", 1.0)],
                              frozenset()])


@st.composite
def parameter_values(draw, good):
    if draw(st.integers(0, 9)) == 0:
        return draw(NO_MAPPING)
    chosen = dict(good)
    for name in draw(st.lists(st.sampled_from(sorted(good)), unique=True, max_size=2)):
        del chosen[name]
    for name in draw(st.lists(st.sampled_from(sorted(good)), unique=True, max_size=3)):
        chosen[name] = draw(values(good[name] or 1.0))
    chosen.update(draw(st.dictionaries(st.one_of(st.text(max_size=3), st.integers()), ANY_NUMBER, max_size=2)))
    return chosen


def check_system(model, values_given):
    system, error = outcome(System, model, values_given)
    names = [str(p) for p in model.parameters]
    if error is not None:
        assert isinstance(error, InputError)
        assert_one_line(error, "parameter_values")
        assert "expected a mapping" in str(error) or any(repr(name) in str(error) for name in names)
        return
    assert finite(system.parameter_values) and system.parameter_values.shape == (len(names),)


@pytest.mark.parametrize("name", sorted(MODELS))
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(data=st.data())
def test_system(name, data):
    model, good = MODELS[name]
    check_system(model, data.draw(parameter_values(good)))


@pytest.mark.parametrize("values_given", [[1, 2], "ab", 5, np.array([1.0, 2.0]),
                                          dict(SLIDER_CRANK_VALUES, g=10**400)])
def test_system_refuses_what_is_no_mapping_of_numbers(values_given):
    check_system(slider_crank.slider_crank_model(), values_given)


# -- simulate -------------------------------------------------------------------------------------

START = slider_crank.initial_state(SYSTEM, math.pi, 1.0)           # case 1: on the switch x_C' = 0
AT_REST = slider_crank.initial_state(SYSTEM, 1.0, 0.0)              # the slider sticks from t = 0
SIMULATE_NAMES = ("t_start:", "t_end:", "rtol:", "atol:", "method:", "formulation:", "t_eval:", "max_steps:",
                  "max_nfev:", "sticking_resolution:", "branch_limit:", "max_step:", "first_step:")


def at_most(limit):
    """A number above ``limit`` becomes ``limit`` (runs stay short); anything else stays."""
    def clip(value):
        if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number, Fraction)):
            return value
        try:
            return limit if float(value) > limit else value
        except (OverflowError, TypeError):
            return limit
    return clip


TIMES = st.one_of(st.floats(1e-3, 0.5), st.floats(1e-13, 1e-3),
                  st.sampled_from([5e-324, 1e-310, 1e-300, 1e-12, np.float32(0.1), Fraction(1, 10)]),
                  ANY_NUMBER.map(at_most(0.5)), NO_NUMBER)
TOLERANCES = st.one_of(
    st.floats(1e-11, 1e-3), st.sampled_from([1e-13, 2.3e-14, 2.2e-14, 1.0, 10.0, 1e300, 5e-324, 0.0, -1e-9]),
    st.lists(st.floats(1e-10, 1e-4), min_size=0, max_size=7),
    st.lists(st.one_of(st.floats(1e-10, 1e-4), st.just(math.nan)), min_size=6, max_size=6),
    ANY_NUMBER, NO_NUMBER)
METHODS = st.one_of(st.sampled_from(SOLVER_METHODS), st.sampled_from(
    ["rk45", "", " RK45", None, 5, ["RK45"], np.array(["RK45", "BDF"]), np.array("RK45"), scipy.integrate.RK23,
     scipy.integrate.OdeSolver, int, b"RK45"]), NO_NUMBER)
FORMULATIONS = st.one_of(st.sampled_from(FORMULATION_NAMES).map(formulation_from_name),
                         st.sampled_from(["baumgarte", None, 5, closedloop.Baumgarte, object(), ["minimal"]]))
OUTPUT_TIMES = st.one_of(
    st.lists(st.floats(0.0, 0.5), max_size=5).map(sorted), st.lists(st.floats(0.0, 0.5), max_size=5),
    st.sampled_from([[], [math.nan], [0.0, 0.0], [-1.0, 0.1], [[0.0, 0.1]], np.linspace(0.0, 0.001, 3), 0.001,
                     [0.0, math.inf], "0.1"]),
    ANY_NUMBER, NO_NUMBER)
COUNTS = st.one_of(st.sampled_from([1, 2, 5, 50, 1000, 10**6, 10**400, 0, -1, 10.0, np.int64(20), np.uint8(3),
                                    True, None, "10"]), ANY_NUMBER, NO_NUMBER)
RESOLUTIONS = st.one_of(st.sampled_from([5e-324, 1e-300, 1e-12, 1e-5, 0.5, 1e300]), st.floats(1e-4, 1.0),
                        ANY_NUMBER, NO_NUMBER)
BRANCH_LIMITS = st.one_of(st.sampled_from([math.inf, 10**400, 5e-324, 1e300]), st.floats(1e-6, 1.0),
                          ANY_NUMBER, NO_NUMBER)
# max_step: none below 1e-3 s but the tiniest (a run of 1e6 steps of 1e-9 s would be long, not wrong).
MAX_STEPS = st.one_of(st.floats(1e-3, 1.0), st.sampled_from([math.inf, 5e-324, 0.0, -1.0, math.nan, 10**400]),
                      NO_NUMBER)
FIRST_STEPS = st.one_of(st.floats(1e-6, 1.0), ANY_NUMBER, NO_NUMBER)
GOOD_OPTIONS = st.fixed_dictionaries({}, optional={
    "rtol": st.floats(1e-11, 1e-3), "atol": st.one_of(st.floats(1e-12, 1e-3), st.lists(st.floats(1e-10, 1e-4),
                                                                                      min_size=6, max_size=6)),
    "method": st.sampled_from(SOLVER_METHODS[:-1]), "formulation": st.sampled_from(
        [formulation_from_name(name) for name in FORMULATION_NAMES if name != "projected"]),
    "t_eval": st.lists(st.floats(0.0, 1e-3), min_size=1, max_size=5, unique=True).map(sorted),
    "max_steps": st.integers(1, 10**6), "max_nfev": st.integers(1, 10**6),
    "sticking_resolution": st.floats(1e-4, 1.0), "branch_limit": st.floats(1e-6, 1.0),
    "max_step": st.floats(1e-3, 1.0), "first_step": st.floats(1e-6, 1.0)})
SIMULATE_OPTIONS = st.fixed_dictionaries({}, optional={
    "rtol": TOLERANCES, "atol": TOLERANCES, "method": METHODS, "formulation": FORMULATIONS, "t_eval": OUTPUT_TIMES,
    "max_steps": COUNTS, "max_nfev": COUNTS, "sticking_resolution": RESOLUTIONS, "branch_limit": BRANCH_LIMITS,
    "max_step": MAX_STEPS, "first_step": FIRST_STEPS})


@settings(max_examples=200, deadline=None)
@given(t_end=TIMES, at_rest=st.booleans(), options=SIMULATE_OPTIONS)
@example(t_end=10**400, at_rest=False, options={})
@example(t_end=0.01, at_rest=False, options={"branch_limit": 10**400})
@example(t_end=0.1, at_rest=False, options={"rtol": [math.nan, 1e-6, 1e-6, 1e-6, 1e-6, 1e-6]})
@example(t_end=0.1, at_rest=False, options={"method": np.array(["RK45", "BDF"])})
@example(t_end=0.1, at_rest=False, options={"method": ["RK45"], "formulation": closedloop.Projected()})
@example(t_end=0.1, at_rest=False, options={"t_eval": [[0.01, 0.02]]})
@example(t_end=0.1, at_rest=False, options={"first_step": -1.0})
@example(t_end=0.5, at_rest=True, options={"sticking_resolution": 5e-324})
@example(t_end=1e-310, at_rest=False, options={"method": "Radau"})
@example(t_end=1e-12, at_rest=False, options={"method": "LSODA"})
@example(t_end=1e-12, at_rest=False, options={"formulation": closedloop.Minimal()})
@example(t_end=0.1, at_rest=False, options={"atol": [1e-6] * 6, "formulation": closedloop.Minimal()})
@example(t_end=0.1, at_rest=False, options={"rtol": [1e-6] * 6, "method": "Radau"})
@example(t_end=0.1, at_rest=False, options={"atol": [1e-6]})
@example(t_end=0.5, at_rest=False, options={"t_eval": 2**1024, "rtol": [1e-6, 10**400]})
def test_simulate(t_end, at_rest, options):
    check_simulate(t_end, at_rest, options)


@settings(max_examples=100, deadline=None)
@given(t_end=st.floats(1e-3, 0.5), at_rest=st.booleans(), options=GOOD_OPTIONS)
def test_simulate_with_valid_options(t_end, at_rest, options):
    check_simulate(t_end, at_rest, options)


def check_simulate(t_end, at_rest, options):
    result, error = outcome(closedloop.simulate, SYSTEM, AT_REST if at_rest else START, t_end, **options)
    if error is not None:
        if isinstance(error, InputError):
            assert_one_line(error, *SIMULATE_NAMES)
        else:
            assert_one_line(error)
        return
    assert isinstance(result, closedloop.SimulationResult)
    assert result.t.size and finite(result.t, result.s, result.sd)
    assert result.s.shape == result.sd.shape == (3, result.t.size)


@pytest.mark.parametrize("formulation, method", [
    (closedloop.ClosedForm(1e6, 1e6), "ode.dop853"), (closedloop.Orthogonal(1e6, 1e6), "ode.dop853"),
    (closedloop.Orthogonal(3e5, 3e5), "DOP853"), (closedloop.NullSpace(3e5, 3e5), "DOP853"),
    (closedloop.Baumgarte(1e6, 1e6), "Radau"), (closedloop.NullSpace(1e6, 1e6), "LSODA")])
def test_the_largest_gains_give_a_result_or_an_integration_error(formulation, method):
    result, error = outcome(closedloop.simulate, SYSTEM, slider_crank.initial_state(SYSTEM, 0.3, 1.0), 0.1,
                            formulation=formulation, method=method, max_steps=50)
    if error is None:
        assert finite(result.t, result.s, result.sd)
    else:
        assert_one_line(error)


@pytest.mark.parametrize("gain", [1e7, 1e100, 1e200])
def test_gains_above_the_limit_are_refused(gain):
    for name in FORMULATION_NAMES:
        _, error = outcome(formulation_from_name, name, gain, 5.0)
        assert isinstance(error, InputError)
        assert_one_line(error, "alpha:", "alpha, beta:")


def test_projection_carries_the_work():
    result, error = outcome(closedloop.simulate, SYSTEM, START, 0.2, formulation=closedloop.Projected(), work=True)
    assert error is None and finite(result.work)


# -- the command line ---------------------------------------------------------------------------

SPELLINGS = ["1", "1.0", "1e0", "+1", " 1 ", "1_0", "0x1", "1,5", "\u0661", "\u22121", ".5", "5.", "-0", "0", "-1",
             "1/2", "pi", "2pi", "1e-300", "5e-324", "inf", "-inf", "Infinity", "nan", "NaN", "1e400", "-1e400",
             "1e309", "", " ", "abc", "-", "1 2", "1\n", "\x00", "0.1.2", "1e", "-h", "--help", "--json", "1" * 400]


def number_texts(low, high):
    """Numbers in ``[low, high]`` written in several ways, odd spellings, and any short text."""
    written = st.floats(low, high).flatmap(lambda x: st.sampled_from(
        [repr(x), f"{x:g}", f"{x:.3e}", f" {x:.4f} ", f"{x:+.2f}", f"{x:E}", f"{x:_.3f}"]))
    other = st.one_of(st.sampled_from(SPELLINGS), st.text(max_size=6))
    return mostly(written, other)


def mostly(good, other, share=0.7):
    """``good`` in about ``share`` of the examples, else ``other``."""
    return st.floats(0.0, 1.0).flatmap(lambda u: good if u < share else other)


def not_above(limit):
    """Text whose number, if it is one, is at most ``limit`` (the run stays short)."""
    def short(text):
        try:
            value = float(text)
        except ValueError:
            return True
        return not (math.isfinite(value) and abs(value) > limit)
    return short


def command_line(args, capsys):
    """Run main(args): the status is 0, 1 or 2; stderr is empty, one error line, or warning lines."""
    capsys.readouterr()
    try:
        with no_hang_and_no_runtime_warning():
            status = main(args)
    finally:
        out, err = capsys.readouterr()             # even after a failure: the next example starts clean
    lines = err.splitlines()
    count(f"exit status {status}")
    assert status in (0, 1, 2), status
    if status == 0:
        assert not lines, lines
        assert not re.search(r"\bnan\b|\binf(inity)?\b", out, re.IGNORECASE), out
    elif len(lines) == 1 and lines[0].startswith("closedloop: error: "):
        assert lines[0].strip() != "closedloop: error:"
    else:
        assert status == 1 and lines and all(line.startswith("closedloop: warning: ") for line in lines), lines
    return status, out


@st.composite
def simulate_arguments(draw):
    options = []

    def add(name, text):
        if draw(st.integers(0, 3)):
            options.append(f"{name}={text}")
        else:
            options.extend([name, text])

    if draw(st.integers(0, 6)) == 0:
        add("--case", draw(st.sampled_from(["1", "2", "3", "4", "0", "5", "x", "", " 2", "1.0", "\uff11"])))
    else:
        add("--phi0", draw(number_texts(-10.0, 10.0).filter(not_above(1e3))))
        add("--dphi0", draw(number_texts(-50.0, 50.0).filter(not_above(50.0))))
    add("--t-end", draw(number_texts(1e-4, 0.5).filter(not_above(0.5))))
    for name in ("--rtol", "--atol"):
        if draw(st.booleans()):
            add(name, draw(st.one_of(number_texts(1e-12, 1e-3).filter(not_above(1e-3)),
                                     st.sampled_from(["1e-14", "1e-13", "0.5", "0.9", "1", "10", "1e10", "1e300",
                                                      "0", "-1e-9"]))))
    if draw(st.booleans()):
        add("--formulation", draw(st.sampled_from(FORMULATION_NAMES + ("", "Baumgarte", "x"))))
    if draw(st.booleans()):
        add("--method", draw(st.sampled_from(SOLVER_METHODS + ("", "rk45", "x"))))
    for name in ("--alpha", "--beta"):
        if draw(st.integers(0, 4)) == 0:
            add(name, draw(st.one_of(number_texts(0.0, 100.0).filter(not_above(100.0)),
                                     st.sampled_from(["1e7", "1e100", "1e200", "-1"]))))
    if draw(st.integers(0, 4)) == 0:
        add("--reading", draw(st.sampled_from(tuple(slider_crank.READINGS) + ("", "x"))))
    if draw(st.booleans()):
        options.append("--json")
    return ["simulate"] + options


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(args=simulate_arguments())
@example(args=["simulate", "--phi0=1", "--dphi0=1", "--t-end=0.1", "--alpha=1e200", "--beta=1e200"])
@example(args=["simulate", "--phi0=3.655e-261", "--dphi0=-25.6339", "--t-end=0.35", "--rtol=1e300"])
@example(args=["simulate", "--phi0=2", "--dphi0=40", "--t-end=0.5", "--rtol=0.5", "--atol=1e-3", "--method=DOP853"])
@example(args=["simulate", "--phi0=4", "--dphi0=-40", "--t-end=0.5", "--rtol=0.9", "--formulation=closed-form",
               "--method=DOP853"])
@example(args=["simulate", "--phi0=1", "--dphi0=1", "--t-end=0.001", "--formulation=orthogonal",
               "--method=ode.dop853", "--alpha=1e6", "--beta=1e6"])
def test_command_line_simulate(args, capsys):
    status, out = command_line(args, capsys)
    if out.strip() and "--json" in args:
        summary = json.loads(out)
        assert finite(list(summary["final"].values()))


ANGLE_TEXTS = ["0", "pi", "2pi", "0.5pi", "1.5*pi", "*pi", "1", "3", "6.2", "-1", "7", "nan", "inf", "1e308pi",
               "-1e308pi", "nanpi", "abc", "", "1e-320", "5e-324"]
SPEED_TEXTS = ["0", "0.5", "1", "2", "3", "-1", "1e3", "1500", "nan", "inf", "1e308pi", "pi", "abc", "", "1e-320"]
GOOD_ANGLES = ["0", "0.5pi", "1", "pi", "3", "1.5*pi", "6.2", "2pi"]
GOOD_SPEEDS = ["0", "0.5", "1", "1.5", "2", "3"]
COUNT_TEXTS = ["1", "2", "3", "0", "-1", "x", "1.5", "", " 2 ", "1e0", "\u0662"]


def ranges(good, anything):
    """START:STOP:N of good values and N <= 3, of anything, or text of another shape."""
    ordered = st.lists(st.sampled_from(good), min_size=2, max_size=2, unique=True).map(
        lambda pair: sorted(pair, key=good.index))
    good_range = st.tuples(ordered, st.integers(1, 3)).map(lambda x: f"{x[0][0]}:{x[0][1]}:{x[1]}")
    return mostly(good_range, st.one_of(
        st.tuples(st.sampled_from(anything), st.sampled_from(anything), st.sampled_from(COUNT_TEXTS)).map(":".join),
        st.sampled_from(["", "0:1", "0:1:2:3", ":::", "0:1:", "0:5e-324:3"]),
        st.text(max_size=6)), share=0.8)


@st.composite
def basin_arguments(draw):
    args = ["basin", f"--phi0={draw(ranges(GOOD_ANGLES, ANGLE_TEXTS))}",
            f"--dphi0={draw(ranges(GOOD_SPEEDS, SPEED_TEXTS))}",
            f"--t-end={draw(number_texts(0.02, 1.0).filter(not_above(1.0)))}"]
    if draw(st.integers(0, 5)) == 0:
        args.append(f"--step={draw(st.sampled_from(['0.02', '0.05', '0.5', '2', '1e-9', '1e-300', '0', 'nan', 'x']))}")
    if draw(st.integers(0, 6)) == 0:
        args.append(f"--workers={draw(st.sampled_from(['1', '0', '-1', 'x', '1.5', '10000']))}")
    return args


@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(args=basin_arguments())
@example(args=["basin", "--phi0=1:3:1", "--dphi0=1:1.5:3", "--t-end=0.372", "--step=1e-300"])
@example(args=["basin", "--phi0=3:6.2:2", "--dphi0=1:1e308pi:2", "--t-end=0.862"])
def test_command_line_basin(args, capsys):
    command_line(args, capsys)


@pytest.mark.parametrize("args", [["simulate", "--phi0=--", "--dphi0=1", "--t-end=0.1"],
                                  ["simulate", "--case=--", "--t-end=0.1"],
                                  ["basin", "--phi0=--", "--dphi0=0:1:1", "--t-end=0.1"]])
def test_an_option_given_as_double_dash_is_an_error(args, capsys):
    # argparse of Python 3.11 hands --opt=-- to cli.py as []: refused as a usage error naming the option
    status, _ = command_line(args, capsys)
    assert status == 2


# -- MultibodyModel ---------------------------------------------------------------------------------

import sympy as sp  # noqa: E402

THETA, X, Y, DTHETA, DX, DY, M, L, G = sp.symbols("theta x y dtheta dx dy m l g")
PENDULUM = dict(coordinates=(THETA, X, Y), velocities=(DTHETA, DX, DY), kinetic_energy=M * (DX**2 + DY**2) / 2,
                potential_energy=M * G * Y, constraints=(X - L * sp.sin(THETA), Y + L * sp.cos(THETA)),
                independent=(THETA,), parameters=(M, L, G))
MODEL_NAMES = tuple(f"{name}:" for name in list(PENDULUM) + ["generalized_forces", "time"]) + (
    "coordinates and velocities must be",)
SYMBOLISH = st.one_of(st.sampled_from([THETA, X, Y, DTHETA, DX, DY, M, L, G, sp.Symbol("w"), sp.Integer(2),
                                       sp.sin(THETA), 2 * X, "x", "dx", b"x", None, True, 1.5]),
                      NO_NUMBER)


@st.composite
def model_fields(draw):
    """The pendulum's fields, a few of them replaced: symbols where expressions go, text, numbers, wrong lengths."""
    fields = dict(PENDULUM)
    for name in draw(st.lists(st.sampled_from(list(PENDULUM) + ["generalized_forces", "time"]), unique=True,
                              max_size=3)):
        if name in ("kinetic_energy", "potential_energy", "time"):
            fields[name] = draw(st.one_of(SYMBOLISH, ANY_NUMBER, st.sampled_from([X * DX, M * G * sp.Symbol("t")])))
        else:
            fields[name] = draw(st.one_of(st.lists(SYMBOLISH, max_size=4).map(tuple), SYMBOLISH,
                                          st.sampled_from([(), (THETA, X), (X, X, Y), (THETA, X, Y, G)])))
    return fields


@settings(max_examples=300, deadline=None)
@given(fields=model_fields())
@example(fields=dict(PENDULUM, constraints=(X - L * sp.sin(THETA), Y + L * sp.cos(THETA), X + Y), independent=()))
@example(fields=dict(PENDULUM, velocities=("dtheta", "dx", "dy")))
def test_multibody_model(fields):
    """Any fields give a model the library can derive, or one line naming the field (InputError)."""
    model, error = outcome(closedloop.MultibodyModel, **fields)
    if error is not None:
        assert isinstance(error, InputError), repr(error)
        assert_one_line(error, *MODEL_NAMES)
        return
    assert len(model.independent) + len(model.constraints) == len(model.coordinates)
    assert all(isinstance(symbol, sp.Symbol) for symbol in model.coordinates + model.velocities)


# -- consistent_initial_state -----------------------------------------------------------------------

PENDULUM_SYSTEM = System(closedloop.MultibodyModel(**PENDULUM), {"m": 2.0, "l": 1.5, "g": 9.81})
Q_VALUES = st.one_of(st.lists(st.floats(-10, 10), min_size=1, max_size=1), st.lists(ANY_NUMBER, max_size=3),
                     NO_NUMBER, ANY_NUMBER)
Z_VALUES = st.one_of(st.lists(st.floats(-3, 3), min_size=2, max_size=2), st.lists(ANY_NUMBER, max_size=3),
                     NO_NUMBER, st.sampled_from([[0.0, 0.0], [0.0, -1.5], [1.5, 0.0]]))


@settings(max_examples=300, deadline=None)
@given(q0=Q_VALUES, qd0=Q_VALUES, z_guess=Z_VALUES)
@example(q0=[math.pi / 2], qd0=[1.0], z_guess=[1.5, 0.0])        # the pendulum level: Phi_z singular there
@example(q0=[0.0], qd0=[0.0], z_guess=[0.0, 4503599627370495.0])  # found here: Newton stopped at |f| = 0.5, its
#                                                                     tolerance taken relative to the guess
@example(q0=[0.0], qd0=[1.1984620899082105e+308], z_guess=[0.0, 0.0])   # found here: R q' overflowed, a warning
def test_consistent_initial_state(q0, qd0, z_guess):
    """Any q0, q0', guess of z give a consistent state, or one line naming the parameter (InputError) or saying
    where the constraints can not be solved (ConvergenceError, SingularConfigurationError)."""
    state, error = outcome(closedloop.consistent_initial_state, PENDULUM_SYSTEM, q0, qd0, z_guess)
    if error is not None:
        if isinstance(error, InputError):
            assert_one_line(error, "q0:", "qd0:", "z_guess:")
        else:
            assert_one_line(error)
        return
    assert finite(state.s, state.sd)
    f, Phi = PENDULUM_SYSTEM.constraints_and_jacobian(state.s)
    assert np.max(np.abs(f)) <= 1e-12 * (1.0 + np.max(np.abs(state.s)))
    assert np.max(np.abs(Phi @ state.sd)) <= 1e-9 * (1.0 + np.max(np.abs(state.sd)))
    assert state.s[0] == pytest.approx(float(np.ravel(q0)[0])) and state.sd[0] == pytest.approx(float(np.ravel(qd0)[0]))
