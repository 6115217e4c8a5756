"""The formulation contract from outside: a toy formulation defined in one file (tests/toy_formulation.py),
registered, and run through every runner it claims, against the library's Augmented and the energy balance."""

import numpy as np
import pytest

from closedloop import Augmented, Formulation, InputError, formulation_from_name, simulate
from closedloop.balance import energy_balance
from closedloop.formulations import REGISTRY, register
from closedloop.simulation.options import methods_taking
from closedloop.slider_crank import get_case, initial_state
from tests.toy_formulation import RangeSpace, StepAltering


@pytest.fixture
def registered():
    register(RangeSpace)
    yield RangeSpace
    del REGISTRY[RangeSpace.name]


@pytest.fixture(scope="module")
def case2(slider_crank):
    return initial_state(slider_crank, get_case(2).phi0, get_case(2).dphi0)


def test_a_registered_toy_is_made_by_its_name_and_takes_every_method(registered):
    toy = formulation_from_name(RangeSpace.name)
    assert type(toy) is RangeSpace and toy.gains is None
    assert methods_taking(toy) == ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA", "ode.dop853")
    with pytest.raises(InputError, match="only the .* take gains"):
        formulation_from_name(RangeSpace.name, alpha=1.0)
    with pytest.raises(InputError, match="toy-range-space.* is RangeSpace's already"):
        register(type("Other", (RangeSpace,), {}))

    class Scaled(RangeSpace):
        name = "toy-scaled"

        def __init__(self, factor):
            self.factor = factor

    with pytest.raises(InputError, match=r"Scaled\(\) must work without arguments"):
        register(Scaled)
    assert "toy-scaled" not in REGISTRY


@pytest.mark.parametrize("method", ["RK45", "DOP853", "Radau", "ode.dop853"])
def test_the_toy_moves_as_augmented_on_every_runner(registered, slider_crank, case2, method):
    """Case 2 over 3 s (its switches included): the same motion as (12) solved as one augmented system."""
    toy = simulate(slider_crank, case2, 3.0, formulation=RangeSpace(), method=method, rtol=1e-10, atol=1e-10)
    reference = simulate(slider_crank, case2, 3.0, formulation=Augmented(), method=method, rtol=1e-10, atol=1e-10)
    assert toy.formulation == "toy-range-space" and toy.method == method
    assert [e.action for e in toy.switch_events] == [e.action for e in reference.switch_events]
    assert len(toy.switch_events) >= 2
    end = np.concatenate((toy.s[:, -1], toy.sd[:, -1]))
    assert np.allclose(end, np.concatenate((reference.s[:, -1], reference.sd[:, -1])), rtol=1e-8, atol=1e-8)
    assert toy.max_constraint_error < 1e-6


@pytest.mark.parametrize("method", ["DOP853", "ode.dop853"])
def test_the_runner_carries_the_toy_s_work_integral(registered, slider_crank, case2, method):
    """With work=True the runner appends W to the toy's state (rule 9): Delta(T + Pi) = W along the run."""
    result = simulate(slider_crank, case2, 3.0, formulation=RangeSpace(), method=method, rtol=1e-10, atol=1e-10,
                      work=True)
    balance = energy_balance(slider_crank, result)
    assert np.max(np.abs(balance.work)) > 1.0                      # the gas force does work
    assert balance.max_residual < 1e-9 * np.max(np.abs(balance.work))


def test_the_toy_runs_with_naive_switching(registered, slider_crank, case2):
    """The naive runner (no events) on a smooth stretch: the toy and Augmented end alike."""
    options = dict(method="DOP853", rtol=1e-10, atol=1e-10, switching="naive")
    toy = simulate(slider_crank, case2, 0.2, formulation=RangeSpace(), **options)
    reference = simulate(slider_crank, case2, 0.2, formulation=Augmented(), **options)
    assert np.allclose(toy.s[:, -1], reference.s[:, -1], rtol=1e-7, atol=1e-7)


def test_a_formulation_that_alters_steps_and_takes_the_compiled_code_is_refused(slider_crank, case2):
    with pytest.raises(InputError, match="toy-step-altering formulation alters the integrator's steps"):
        simulate(slider_crank, case2, 1.0, formulation=StepAltering(), method="ode.dop853")
    result = simulate(slider_crank, case2, 0.5, formulation=StepAltering(), method="RK45")
    assert result.method == "RK45" and result.t[-1] == 0.5


def test_the_contract_is_abstract():
    """A subclass without a name or accelerations can not be made, nor registered."""
    class Nameless(Formulation):
        def accelerations(self, system, t, s, sd, mode=None):
            return sd

    class Still(Formulation):
        name = "still"

    for cls in (Formulation, Nameless, Still):
        with pytest.raises(TypeError, match="abstract"):
            cls()
        with pytest.raises(InputError, match="concrete subclass"):
            register(cls)
