"""Bad input: a clear error naming the parameter and its range, raised before any integration."""

import math

import numpy as np
import pytest

import closedloop.simulation.solve_ivp_runner as solve_ivp_runner
from closedloop import Baumgarte, InitialState, InputError, Orthogonal, formulation_from_name, simulate
from closedloop.slider_crank import SliderCrankParameters, get_case, get_reading, initial_state


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
    with pytest.raises(InputError, match=r"^formulation: unknown 'lagrange'; choose one of augmented"):
        formulation_from_name("lagrange")
    with pytest.raises(InputError, match=r"^method: unknown 'Euler'; choose one of .*LSODA"):
        simulate(slider_crank, state, 1.0, method="Euler")
    with pytest.raises(InputError, match=r"^reading: unknown 'hundreds'; choose one of decimal-opposing"):
        get_reading("hundreds")


def test_an_inconsistent_initial_state_is_refused(slider_crank):
    with pytest.raises(InputError, match=r"^initial_state: not consistent"):
        simulate(slider_crank, InitialState(np.array([math.pi, math.pi, 2.0]), np.zeros(3)), 1.0)
