"""simulate() and classify_motion() refuse bad arguments before any work, naming the parameter."""

import numpy as np
import pytest

from closedloop import InputError, simulate
from closedloop.simulation.options import RTOL_FLOOR
from closedloop.slider_crank import classify_motion, initial_state, slider_crank_system


@pytest.fixture(scope="module")
def setup():
    system = slider_crank_system()
    return system, initial_state(system, 1.0, 1.0)


@pytest.mark.parametrize("keywords, message", [
    ({"rtol": "1e-6"}, r"^rtol: must be finite numbers, got '1e-6'$"),
    ({"rtol": None}, r"^rtol: must be finite numbers, got None$"),
    ({"atol": True}, r"^atol: must be finite numbers, got True$"),
    ({"rtol": 1e-16, "atol": 1e-16}, r"^rtol: must be >= 2.22e-14, the tightest float64 can deliver"),
    ({"rtol": [1e-9, -1.0, 1e-9, 1e-9, 1e-9, 1e-9]}, r"^rtol: must be finite numbers > 0"),
    ({"t_eval": []}, r"^t_eval: holds no time"),
    ({"t_eval": [0.0, np.nan, 0.5]}, r"^t_eval: must be finite"),
    ({"t_eval": "0 0.5"}, r"^t_eval: must be finite numbers, got '0 0.5'$"),
    ({"t_eval": [0.0, 0.5, 0.5, 1.0]}, r"^t_eval: must increase strictly within \[0, 1\]$"),   # a repeat
    ({"t_eval": [0.0, 1.5]}, r"^t_eval: must increase strictly within \[0, 1\]$"),
    ({"t_eval": [[0.0, 0.5]]}, r"^t_eval: must be a flat list of numbers, got an array of shape \(1, 2\)$"),
    ({"t_start": "0"}, r"^t_start: must be a finite number \[s\], got '0'$"),
    ({"max_steps": np.float64(5.0)}, r"^max_steps: must be an integer >= 1, got 5.0$"),
    ({"max_nfev": 0}, r"^max_nfev: must be an integer >= 1, got 0$"),
    ({"sticking_resolution": -1}, r"^sticking_resolution: must be a finite number > 0 s, got -1$"),
    ({"branch_limit": "inf"}, r"^branch_limit: must be a number > 0"),
])
def test_bad_arguments_are_refused_with_the_parameter_named(setup, keywords, message):
    system, state = setup
    with pytest.raises(InputError, match=message):
        simulate(system, state, 1.0, **keywords)


def test_numpy_numbers_are_numbers(setup):
    system, state = setup
    result = simulate(system, state, np.int64(1), rtol=np.float32(1e-6), atol=np.float64(1e-6),
                      max_steps=np.int32(10_000), t_eval=np.array([0.0, 0.5, 1.0]))
    assert result.t.tolist() == [0.0, 0.5, 1.0]
    assert RTOL_FLOOR == pytest.approx(100 * np.finfo(float).eps)
    floor = simulate(system, state, 0.1, rtol=RTOL_FLOOR, atol=1e-14)      # the floor itself is allowed
    assert floor.t[-1] == 0.1


@pytest.mark.parametrize("value", [None, "result", 3.0])
def test_classify_motion_wants_a_result(value):
    with pytest.raises(InputError, match=r"^result: expected a SimulationResult, got "):
        classify_motion(value)


@pytest.mark.parametrize("masses, message", [
    ({"m1": -10.0}, r"^system: the mass matrix M of \(5\) at the initial state has the eigenvalues -1.34, 0.48, 6.01: "
                    r"the kinetic energy s'\^T M s' / 2 is not positive"),
    ({"m1": 0.0, "m2": 0.0, "m3": 0.0}, r"^system: the mass matrix M of \(5\) at the initial state has the "
                                         r"eigenvalues 0, 0, 0"),
])
@pytest.mark.parametrize("name", ["minimal", "baumgarte"])
def test_a_kinetic_energy_that_is_not_positive_is_refused(masses, message, name):
    """A negative or vanishing inertia is refused before the run, whatever the formulation (Minimal raised
    a raw LinAlgError, Baumgarte blamed a kinematic singularity, and m1 = -10 ran without complaint)."""
    from closedloop import System, consistent_initial_state
    from closedloop.formulations import formulation_from_name
    from closedloop.four_bar import four_bar_model

    data = {"l0": 3.0, "l1": 1.0, "l2": 3.0, "l3": 1.2, "m1": 1.0, "m2": 2.0, "m3": 1.0, "g": 9.81, **masses}
    system = System(four_bar_model(), data)
    state = consistent_initial_state(system, [-np.pi / 2], [1.0], [0.0, -np.pi / 2])
    with pytest.raises(InputError, match=message):
        simulate(system, state, 1.0, formulation=formulation_from_name(name))


@pytest.mark.parametrize("misspelt, meant", [("max_stp", "max_step"), ("rtoll", "rtol"), ("stop_wen", "stop_when")])
def test_a_misspelt_keyword_is_refused_with_the_close_match_and_the_advice_works(setup, misspelt, meant):
    """max_stp=0.01 went on to solve_ivp, which warned and ignored it: the run was not the one asked for."""
    system, state = setup
    value = {"max_step": 0.01, "rtol": 1e-6, "stop_when": lambda t, s, sd: t - 0.5}[meant]
    with pytest.raises(InputError) as error:
        simulate(system, state, 1.0, **{misspelt: value})
    message = str(error.value)
    assert message.startswith(f"{misspelt}: unknown keyword of simulate(); did you mean {meant!r}? simulate() takes "
                              "system, initial_state, t_end, t_start, formulation, method, rtol, atol, ")
    assert message.endswith("and for RK45 the solver options first_step, max_step")
    result = simulate(system, state, 1.0, **{meant: value})               # the advice, followed
    if meant == "max_step":
        assert np.max(result.step_sizes) <= 0.01 * (1 + 1e-12)
    elif meant == "stop_when":
        assert result.stopped_at == pytest.approx(0.5)
    else:
        assert result.rtol == 1e-6


def test_a_solver_option_of_another_method_is_refused_naming_those_that_take_it(setup):
    system, state = setup
    with pytest.raises(InputError, match=r"^min_step: not a solver option of RK45 \(only of LSODA\); simulate\(\) "
                                         r"takes .*, and for RK45 the solver options first_step, max_step$"):
        simulate(system, state, 1.0, min_step=1e-4)
    result = simulate(system, state, 1.0, method="LSODA", min_step=1e-6)       # where it is taken
    assert np.min(result.step_sizes[:-1]) >= 1e-6


@pytest.mark.parametrize("stop_when, shown", [
    (lambda t, s, sd: float("nan"), "nan"),
    (lambda t, s, sd: s[0] > 2.0, "False"),
    (lambda t, s, sd: np.inf, "inf"),
    (lambda t, s, sd: 1.0 + 2.0j, r"\(1\+2j\)"),
])
def test_a_stop_when_that_is_no_finite_number_is_refused_before_the_run(setup, stop_when, shown):
    """A NaN never crosses zero: the run went on with stop_when silently off; a bool crosses at every False."""
    system, state = setup
    with pytest.raises(InputError, match=rf"^stop_when: must return a finite number \(it stops the run where it "
                                         rf"crosses zero upward\), got {shown} at t = 0 s$"):
        simulate(system, state, 1.0, stop_when=stop_when)


@pytest.mark.parametrize("method", ["RK45", "LSODA", "ode.dop853"])
def test_a_stop_when_that_turns_nan_during_the_run_is_refused_with_its_time(setup, method):
    from closedloop import ClosedForm

    system, state = setup

    def stop_when(t, s, sd):
        return -1.0 if t < 0.3 else float("nan")

    with pytest.raises(InputError) as error:
        simulate(system, state, 1.0, formulation=ClosedForm(), method=method, stop_when=stop_when)
    message = str(error.value)
    assert message.startswith("stop_when: must return a finite number") and message.endswith(" s")
    assert 0.3 <= float(message.split("at t = ")[1].split(" s")[0]) < 0.6      # the first step end past 0.3 s


def test_a_stop_when_that_raises_is_named_with_its_time(setup):
    system, state = setup
    with pytest.raises(InputError, match=r"^stop_when: stop_when\(t, s, sd\) raised IndexError at t = 0 s: "):
        simulate(system, state, 1.0, stop_when=lambda t, s, sd: s[7])


def test_an_initial_state_of_strings_is_refused_naming_it(setup):
    """InitialState(['a', 'b', 'c'], [0, 0, 0]) raised numpy's ValueError ('could not convert string to float')."""
    from closedloop import InitialState

    with pytest.raises(InputError, match=r"^InitialState: s must be numbers, got \['a', 'b', 'c'\]$"):
        InitialState(["a", "b", "c"], [0, 0, 0])
    system, state = setup
    result = simulate(system, InitialState(list(state.s), list(state.sd)), 0.1)    # numbers: a state
    assert result.t[-1] == pytest.approx(0.1)
