"""Bad input: a clear error naming the parameter, its range and the value, raised before any integration;
Python and numpy numbers accepted alike.

The command line's one-line errors are checked in test_cli.py.
"""

import math

import numpy as np
import pytest

import closedloop.simulation.solve_ivp_runner as solve_ivp_runner
import closedloop.validation as validation
from closedloop import (Baumgarte, InitialState, InputError, Orthogonal, System, baumgarte_from_step,
                        formulation_from_name, simulate)
from closedloop.slider_crank import SliderCrankParameters, get_case, get_reading, initial_state
from closedloop.studies.basin import basin_map


@pytest.fixture(autouse=True)
def no_integration(monkeypatch):
    """Any call of solve_ivp during these tests is a failure: errors must come first."""
    def forbidden(*args, **kwargs):
        raise AssertionError("solve_ivp was called before the input was validated")
    monkeypatch.setattr(solve_ivp_runner, "solve_ivp", forbidden)


@pytest.mark.parametrize("name", ["m1", "m2", "m3", "I1", "I2", "l1", "l2"])
@pytest.mark.parametrize("value", [0.0, -1.0, math.nan, math.inf])
def test_masses_inertias_and_lengths_must_be_positive_and_finite(name, value):
    with pytest.raises(InputError, match=rf"^{name}: must be (> 0|a finite number)"):
        SliderCrankParameters(**{name: value})


def test_a_crank_as_long_as_the_rod_is_refused_with_the_reason():
    for l1 in (3.5, 4.0):
        with pytest.raises(InputError, match=r"^l1: must be < l2 = 3\.5 m.*cannot turn a full revolution"):
            SliderCrankParameters(l1=l1)


@pytest.mark.parametrize("phi0, dphi0", [(math.nan, 1.0), (1.0, math.inf), (math.inf, 0.0)])
def test_initial_values_must_be_finite(slider_crank, phi0, dphi0):
    with pytest.raises(InputError, match=r"must be a finite number"):
        initial_state(slider_crank, phi0, dphi0)


@pytest.fixture
def state(slider_crank):
    return initial_state(slider_crank, math.pi, 1.0)


@pytest.mark.parametrize("t_end", [0.0, -1.0])
def test_t_end_must_be_positive(slider_crank, state, t_end):
    with pytest.raises(InputError, match=r"^t_end: must be > t_start = 0"):
        simulate(slider_crank, state, t_end)


@pytest.mark.parametrize("name", ["rtol", "atol"])
@pytest.mark.parametrize("value", [0.0, -1e-6, math.nan])
def test_tolerances_must_be_positive(slider_crank, state, name, value):
    with pytest.raises(InputError, match=rf"^{name}: must be a finite number > 0, got "):
        simulate(slider_crank, state, 1.0, **{name: value})


@pytest.mark.parametrize("kind", [Baumgarte, Orthogonal])
@pytest.mark.parametrize("gain", ["alpha", "beta"])
def test_baumgarte_gains_must_not_be_negative(kind, gain):
    with pytest.raises(InputError, match=rf"^{gain}: must be a finite number >= 0"):
        kind(**{gain: -1.0})


def test_unknown_names_are_refused_with_the_choices(slider_crank, state):
    with pytest.raises(InputError, match=r"^case: unknown 5; choose one of 1, 2, 3, 4"):
        get_case(5)
    with pytest.raises(InputError, match=r"^case: unknown True; choose one of 1, 2, 3, 4"):
        get_case(True)                                  # True == 1: it was case 1
    with pytest.raises(InputError, match=r"^formulation: unknown 'lagrange'; choose one of augmented"):
        formulation_from_name("lagrange")
    with pytest.raises(InputError, match=r"^method: unknown 'Euler'; choose one of .*LSODA"):
        simulate(slider_crank, state, 1.0, method="Euler")
    with pytest.raises(InputError, match=r"^reading: unknown 'hundreds'; choose one of decimal-opposing"):
        get_reading("hundreds")


def test_an_inconsistent_initial_state_is_refused(slider_crank):
    with pytest.raises(InputError, match=r"^initial_state: not consistent"):
        simulate(slider_crank, InitialState(np.array([math.pi, math.pi, 2.0]), np.zeros(3)), 1.0)


@pytest.mark.parametrize("kwargs, message", [
    ({"t_end": 0.0}, "t_end: must be a finite number > 0"),
    ({"step": -0.1}, "step: must be a finite number > 0"),
    ({"step": 30.0}, "step: must be <= t_end"),
    ({"workers": 0}, "workers: must be an integer"),
])
def test_basin_map_refuses_bad_input_before_integrating(kwargs, message):
    with pytest.raises(InputError, match=message):
        basin_map([1.0, 2.0], [0.5], **{"t_end": 20.0, **kwargs})
    with pytest.raises(InputError, match="phi0: values must increase"):
        basin_map([2.0, 1.0], [0.5])


@pytest.mark.parametrize("value", [5, 5.0, np.int64(5), np.float64(5.0), np.float32(5.0)])
def test_python_and_numpy_numbers_are_accepted_alike(value):
    assert validation.finite_number("step", value, minimum=0.0, strict=True) == 5.0
    assert isinstance(validation.positive_number("t_end", value), float)
    assert SliderCrankParameters(m3=value).m3 == value


@pytest.mark.parametrize("value", [np.int64(5), 5, np.int32(5)])
def test_numpy_integers_are_integers(value):
    assert validation.positive_integer("n_steps", value) == 5
    assert type(validation.positive_integer("n_steps", value)) is int


@pytest.mark.parametrize("value, shown", [(True, "True"), ("5", "'5'"), (None, "None"), (np.bool_(True), "True")])
def test_bool_text_and_none_are_refused_with_the_parameter_named(value, shown):
    with pytest.raises(InputError, match=rf"^step: must be a finite number > 0 s, got {shown}$"):
        validation.positive_number("step", value, unit="s")
    with pytest.raises(InputError, match=rf"^n_steps: must be an integer >= 1, got {shown}$"):
        validation.positive_integer("n_steps", value)
    with pytest.raises(InputError, match=r"^alpha: must be a finite number >= 0, got "):
        Baumgarte(alpha=value)


def test_each_message_names_the_range_and_the_value():
    with pytest.raises(InputError, match=r"^g: must be a finite number >= 0 m/s\^2, got -9\.81$"):
        SliderCrankParameters(g=-9.81)
    with pytest.raises(InputError, match=r"^a2: must lie on the rod, 0 <= a2 <= l2 = 3\.5 m, got 4 m$"):
        SliderCrankParameters(a2=4.0)                   # beyond the rod's end, within twice its length
    assert SliderCrankParameters(a2=3.5).a2 == 3.5      # at its end: allowed
    with pytest.raises(InputError, match=r"^step: must be a finite number > 0 s, got nan$"):
        validation.positive_number("step", np.float64("nan"), unit="s")
    with pytest.raises(InputError, match=r"^workers: must be an integer from 1 to 8, got 9$"):
        validation.integer("workers", 9, minimum=1, maximum=8)
    with pytest.raises(InputError, match=r"^x: must be a finite number from 0 to 1, got 1\.5$"):
        validation.finite_number("x", 1.5, minimum=0.0, maximum=1.0)
    with pytest.raises(InputError, match=r"^basis: unknown 'lu'; choose one of svd, pivoted$"):
        validation.one_of("basis", "lu", ("svd", "pivoted"))
    with pytest.raises(InputError, match=r"^case: unknown \[1\]; choose one of 1, 2, 3, 4$"):
        get_case([1])                                   # unhashable: refused, not a TypeError
    with pytest.raises(InputError, match=r"^q0: need 1 values, got 2$"):
        validation.finite_array("q0", [1.0, 2.0], size=1)
    with pytest.raises(InputError, match=r"^q0: must be a flat list of numbers, got an array of shape \(1, 1\)$"):
        validation.finite_array("q0", [[1.0]], size=1)          # said "need 1 values, got 1"
    with pytest.raises(InputError, match=r"^rtol: must be a flat list of numbers, got an array of shape \(1, 2\)$"):
        validation.finite_array("rtol", [[1e-6, 1e-6]])         # was returned 2-d, as no docstring said
    assert validation.finite_number("x", 1.0, minimum=0.0, maximum=1.0) == 1.0   # both bounds: closed
    assert get_case(np.int64(2)).phi0 == math.pi / 2


def test_numpy_numbers_reach_the_library_unrefused(slider_crank):
    rule = baumgarte_from_step(np.float64(0.01))
    assert (rule.alpha, rule.beta) == pytest.approx((100.0, 100.0 * math.sqrt(2.0)))
    state = initial_state(slider_crank, np.float64(math.pi), np.int64(1))
    assert state.sd[0] == 1.0 and state.s[2] == pytest.approx(1.5, abs=1e-14)   # x_C = l2 - l1 at phi = pi


def test_the_energy_bookkeeping_refuses_another_system(slider_crank):
    from closedloop.studies.energy import crank_landscape

    values = dict(zip(map(str, slider_crank.model.parameters), slider_crank.parameter_values))
    plain = System(slider_crank.model, values)
    with pytest.raises(InputError, match=r"^system: expected a SliderCrankSystem, got System$"):
        crank_landscape(plain, [0.0, 1.0])
    assert crank_landscape(slider_crank, [0.0, 1.0]).slope[0] == pytest.approx(0.0, abs=1e-14)  # x_C' = 0 at phi = 0


def test_an_initial_state_at_a_dead_position_is_refused_with_a_remedy_for_starting():
    """There q' does not fix z'; the message used to be simulate's ("use the NullSpace formulation"),
    which does not build a state."""
    from closedloop import SingularConfigurationError
    from closedloop.slider_crank import slider_crank_system

    rocking = slider_crank_system(SliderCrankParameters(l1=3.5, l2=2.0, full_rotation=False))
    dead = math.asin(2.0 / 3.5)
    with pytest.raises(SingularConfigurationError, match=r"^q0: Phi_z is singular at q0 = \[0\.608.*start away"):
        initial_state(rocking, dead, 1.0)
    assert initial_state(rocking, dead - 0.01, 1.0).sd[0] == 1.0         # just beside it, a state


WRONG_KINDS = [None, "x", 1.5, [1, 2], object(), np.array([1.0, 2.0]), True]


def _entry_points():
    """Each public entry point with one argument left open: ``{name: (call, the parameter its error names)}``."""
    import sympy as sp

    from closedloop import MultibodyModel, consistent_initial_state, derive, null_space_basis
    from closedloop.fixed_step import rk4
    from closedloop.formulations import project_state
    from closedloop.slider_crank import classify_motion, slider_crank_system

    system = slider_crank_system()
    state = initial_state(system, 1.0, 1.0)
    x, dx = sp.symbols("x dx")
    return {
        "simulate(system)": (lambda b: simulate(b, state, 1.0), "system:"),
        "simulate(multipliers)": (lambda b: simulate(system, state, 1.0, multipliers=b), "multipliers:"),
        "simulate(work)": (lambda b: simulate(system, state, 1.0, work=b), "work:"),
        "simulate(max_segments)": (lambda b: simulate(system, state, 1.0, max_segments=b), "max_segments:"),
        "derive": (derive, "model:"),
        "consistent_initial_state(system)": (lambda b: consistent_initial_state(b, [1.0], [1.0], [3.0, 4.0]),
                                             "system:"),
        "initial_state(system)": (lambda b: initial_state(b, 1.0, 1.0), "system:"),
        "slider_crank_system(torque)": (lambda b: slider_crank_system(torque=b), "torque:"),
        "rk4(system)": (lambda b: rk4(b, Baumgarte(), state.s, state.sd, 0.01, 3), "system:"),
        "rk4(formulation)": (lambda b: rk4(system, b, state.s, state.sd, 0.01, 3), "formulation:"),
        "null_space_basis": (null_space_basis, "Phi:"),
        "project_state": (lambda b: project_state(system, b, state.sd), "s, sd:"),
        "MultibodyModel(kinetic_energy)": (lambda b: MultibodyModel((x,), (dx,), b, 0, (), (x,)),
                                           "kinetic_energy:"),
        "InitialState": (lambda b: InitialState(b, [0.0, 0.0, 0.0]), "InitialState:"),
        "classify_motion": (lambda b: classify_motion(b), "result:"),
    }


@pytest.mark.parametrize("name", list(_entry_points()))
def test_every_entry_point_refuses_a_wrong_kind_of_argument_with_input_error(name):
    """Each raised AttributeError, TypeError or numpy's ValueError ("the truth value of an array ... is
    ambiguous"), or took a wrong value on: the error is an InputError on one line that names the parameter."""
    call, parameter = _entry_points()[name]
    refused = []
    for value in WRONG_KINDS:
        try:
            call(value)
        except InputError as error:
            assert "\n" not in str(error) and str(error).startswith(parameter), (value, str(error))
            refused.append(value)
        except AssertionError as error:                 # a value of the right kind: the run was about to start
            assert "solve_ivp was called" in str(error)
        except Exception as error:                      # anything else escapes the library: the failure
            pytest.fail(f"{name}({value!r}) raised {type(error).__name__}: {error}")
    assert len(refused) >= len(WRONG_KINDS) - 2, (name, refused)   # 1.5 or True may be of the right kind
