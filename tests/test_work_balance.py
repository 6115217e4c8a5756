"""The work of the applied forces integrated with the state, and the energy balance Delta(T + Pi) = W."""

import math

import numpy as np
import pytest

from closedloop import Baumgarte, InputError, Minimal, simulate
from closedloop.balance import energy_balance
from closedloop.slider_crank import (CASES, DEFAULT_READING, OMEGA, SliderCrankParameters, SliderCrankSystem,
                                     get_reading, initial_state, slider_crank_system)


def test_work_of_a_constant_torque_is_torque_times_angle():
    """Ripple off, gas force off: W(t) = M (phi(t) - phi(0)) exactly."""
    parameters = SliderCrankParameters()
    values = parameters.as_dict()
    values.update(torque_mean=41.45, torque_ripple=0.0, omega=OMEGA)
    system = SliderCrankSystem(parameters, get_reading(DEFAULT_READING), values, None)
    state = initial_state(system, CASES[2].phi0, CASES[2].dphi0)
    result = simulate(system, state, 10.0, formulation=Baumgarte(), method="DOP853", rtol=1e-10, atol=1e-10,
                      t_eval=np.linspace(0, 10, 101), work=True)
    angle = result.coordinate("phi") - state.s[0]
    assert np.max(np.abs(angle)) > 2 * math.pi
    assert np.max(np.abs(result.work - 41.45 * angle)) < 1e-7


@pytest.mark.parametrize("formulation", [Minimal(), Baumgarte(5, 5)], ids=lambda f: f.name)
def test_energy_balance_with_torque_and_gas_force(slider_crank, formulation):
    state = initial_state(slider_crank, CASES[2].phi0, CASES[2].dphi0)
    result = simulate(slider_crank, state, 20.0, formulation=formulation, method="DOP853", rtol=1e-11, atol=1e-11,
                      work=True)
    balance = energy_balance(slider_crank, result)
    assert np.max(np.abs(balance.work)) > 100.0           # the gas force removed real energy
    assert balance.max_residual < 1e-6
    assert len(result.switch_events) > 5                  # ... across many switches


def test_work_is_constant_while_stuck(slider_crank):
    state = initial_state(slider_crank, CASES[3].phi0, CASES[3].dphi0)
    result = simulate(slider_crank, state, 32.0, method="DOP853", rtol=1e-10, atol=1e-10, work=True)
    start, end = result.sticking_intervals[0]
    held = (result.t >= start) & (result.t <= end)
    assert held.sum() >= 2 and np.ptp(result.work[held]) == 0.0
    assert energy_balance(slider_crank, result).max_residual < 1e-6


def test_conservative_system_does_no_work(conservative_slider_crank):
    state = initial_state(conservative_slider_crank, 1.0, 2.0)
    result = simulate(conservative_slider_crank, state, 5.0, method="DOP853", rtol=1e-11, atol=1e-11, work=True)
    assert np.all(result.work == 0.0)
    assert energy_balance(conservative_slider_crank, result).max_residual < 1e-7


def test_energy_balance_needs_the_work():
    system = slider_crank_system()
    result = simulate(system, initial_state(system, 1.0, 1.0), 0.1)
    with pytest.raises(InputError, match="work=True"):
        energy_balance(system, result)
