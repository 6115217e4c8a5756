"""The basin map: the batch integrator against simulate(), the boundary, the sticking rule, the command."""

import math

import numpy as np
import pytest

from closedloop import Minimal, simulate
from closedloop.studies.basin import (basin_map, boundary_cells, compare_outcomes, grid_values, integrate_outcomes,
                              reference_outcomes)
from closedloop.slider_crank import CASES, GasForce, initial_state

#: A 12 x 10 grid that cuts across the basin boundary (see the chapter's map).
SMALL_PHI0 = grid_values(0.5 * math.pi, 1.5 * math.pi, 12)
SMALL_DPHI0 = grid_values(0.5, 2.0, 10)


@pytest.fixture(scope="module")
def small_map():
    return basin_map(SMALL_PHI0, SMALL_DPHI0, 20.0)


@pytest.fixture(scope="module")
def small_reference():
    return reference_outcomes(SMALL_PHI0, SMALL_DPHI0, 20.0)


def test_small_grid_has_both_outcomes_and_a_boundary(small_reference):
    """The agreement test below is only worth something if the grid crosses the boundary."""
    assert 0.2 < np.mean(small_reference == 1) < 0.8
    assert np.sum(boundary_cells(small_reference)) >= 10


def test_map_agrees_with_per_trajectory_simulate_off_the_boundary(small_map, small_reference):
    """At least 99.5 % agreement: on 120 cells that allows no disagreement except on the boundary."""
    agreement = compare_outcomes(small_map.outcome, small_reference)
    assert agreement.cells == 120
    assert all(agreement.on_boundary), agreement.disagreeing
    assert len(agreement.disagreeing) <= 1


def test_batch_final_state_matches_simulate_to_the_step_error(slider_crank):
    """Case 3 swings for 20 s through many switches: the batch and simulate (rtol 1e-10) end together."""
    case = CASES[3]
    batch = integrate_outcomes(slider_crank, [case.phi0], [case.dphi0], 20.0)
    result = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 20.0,
                      formulation=Minimal(), method="DOP853", rtol=1e-10, atol=1e-10)
    assert batch.switch_events[0] >= 5
    assert batch.final_phi[0] == pytest.approx(result.coordinate("phi")[-1], abs=1e-6)
    assert batch.final_dphi[0] == pytest.approx(result.velocity("phi")[-1], abs=1e-6)
    assert batch.excursion[0] == pytest.approx(np.max(np.abs(result.coordinate("phi") - case.phi0)), abs=1e-4)
    assert batch.max_constraint_error < 1e-12


def test_batch_releases_a_stuck_slider_where_simulate_does():
    """A torque ripple of 60 N m frees the slider: stuck at t = 0, released, stuck again, as simulate finds."""
    from closedloop.slider_crank import OMEGA, SliderCrankParameters, SliderCrankSystem, get_reading

    reading, parameters = get_reading("decimal-opposing"), SliderCrankParameters()
    values = dict(parameters.as_dict(), torque_mean=reading.torque_mean, torque_ripple=60.0, omega=OMEGA)
    system = SliderCrankSystem(parameters, reading, values, GasForce(reading))
    phi0 = 1.34
    result = simulate(system, initial_state(system, phi0, 0.0), 4.0, formulation=Minimal(), method="DOP853",
                      rtol=1e-10, atol=1e-10)
    (start, end), *later = result.sticking_intervals
    assert start == 0.0 and len(later) >= 2
    batch = integrate_outcomes(system, [phi0], [0.0], 4.0, finish_early=False)
    assert batch.stuck_at[0] == 0.0
    # one release rule (closedloop.simulation.switching.locate_release) for both: the same root
    assert batch.released_at[0] == pytest.approx(end, abs=1e-11)
    assert batch.final_phi[0] == pytest.approx(result.coordinate("phi")[-1], abs=1e-6)
    assert batch.final_dphi[0] == result.velocity("phi")[-1] == 0.0     # stuck again at the end


def test_boundary_cells_are_those_with_a_neighbour_of_the_other_outcome():
    outcome = np.array([[0, 0, 0, 0],
                        [0, 0, 1, 1],
                        [0, -1, 1, 1]])
    expected = np.array([[0, 0, 1, 1],
                         [0, 1, 1, 1],
                         [0, 0, 0, 0]], bool)       # -1 (not computed) is no one's neighbour
    np.testing.assert_array_equal(boundary_cells(outcome), expected)
    agreement = compare_outcomes(np.array([[0, 1], [1, 1]]), np.array([[0, 0], [1, 1]]))
    assert agreement.disagreeing == [(0, 1)] and agreement.on_boundary == [True]
    assert agreement.fraction == 0.75


def test_two_workers_give_the_same_map_as_one():
    phi0, dphi0 = grid_values(0.0, 2 * math.pi, 8), grid_values(0.0, 3.0, 5)
    one = basin_map(phi0, dphi0, 3.0)
    two = basin_map(phi0, dphi0, 3.0, workers=2)
    np.testing.assert_array_equal(one.outcome, two.outcome)
    np.testing.assert_allclose(one.excursion, two.excursion, rtol=1e-12)
    assert two.workers == 2 and one.outcome.shape == (5, 8)

