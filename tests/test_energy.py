"""Energy: conserved without torque and gas force; balanced against their work with them."""

import numpy as np
import pytest

from closedloop import Augmented, Baumgarte, Minimal, Orthogonal, simulate
from closedloop.slider_crank import CASES, drive_torque, gas_force, initial_state

FORMULATIONS = [Augmented(), Baumgarte(5, 5), Orthogonal(5, 5), Minimal()]


@pytest.mark.parametrize("formulation", FORMULATIONS, ids=lambda f: f.name)
@pytest.mark.parametrize("number", [1, 2])
def test_energy_is_conserved_without_torque_and_gas_force(conservative_slider_crank, formulation, number):
    system = conservative_slider_crank
    case = CASES[number]
    state = initial_state(system, case.phi0, case.dphi0)
    result = simulate(system, state, 20.0, formulation=formulation, method="DOP853", rtol=1e-11, atol=1e-11)
    energy = system.energy(result.s, result.sd)
    initial = system.energy(state.s, state.sd)
    assert abs(initial) > 100.0                      # a relative test needs a non-trivial energy
    assert np.max(np.abs(energy - initial)) / abs(initial) < 1e-8
    assert np.ptp(result.coordinate("phi")) > 1.0    # the mechanism really moved


def test_energy_balance_with_torque_and_gas_force(slider_crank):
    """T + Pi changes by the work of the torque on phi and of the gas force on x_C (case 2)."""
    case = CASES[2]
    state = initial_state(slider_crank, case.phi0, case.dphi0)
    t = np.linspace(0.0, 20.0, 40001)
    result = simulate(slider_crank, state, 20.0, formulation=Minimal(), method="DOP853",
                      rtol=1e-11, atol=1e-11, t_eval=t)
    phi_dot, x, x_dot = result.velocity("phi"), result.coordinate("x"), result.velocity("x")
    power = drive_torque(t) * phi_dot + (+1) * gas_force(x, x_dot) * x_dot   # paper's reading: +F
    work = np.concatenate(([0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(t))))
    energy = slider_crank.energy(result.s, result.sd)
    # trapezoidal quadrature of a power with kinks at the switches: 1e-3 J out of ~1000 J of work
    assert np.max(np.abs(energy - energy[0] - work)) < 2e-3
    assert np.max(np.abs(work)) > 100.0


@pytest.mark.parametrize("formulation", FORMULATIONS, ids=lambda f: f.name)
def test_a_new_mechanism_four_bar_linkage_conserves_energy_and_stays_closed(four_bar, formulation):
    """Grashof crank-rocker (l1 + l0 < l2 + l3): the crank turns fully; T + Pi constant, loop closed."""
    from closedloop import consistent_initial_state

    state = consistent_initial_state(four_bar, [0.5], [6.0], [1.0, 1.8])
    result = simulate(four_bar, state, 10.0, formulation=formulation, method="DOP853", rtol=1e-11, atol=1e-11)
    energy = four_bar.energy(result.s, result.sd)
    initial = four_bar.energy(state.s, state.sd)
    assert np.max(np.abs(energy - initial)) / abs(initial) < 1e-8
    assert result.max_constraint_error < 1e-7
    assert np.ptp(result.coordinate("theta1")) > 2 * np.pi      # the crank turned a full revolution
