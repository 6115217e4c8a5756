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
