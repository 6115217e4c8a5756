"""The batch integrator of the basin map on a system other than the slider-crank: the four-bar.

The four-bar of ``conftest.four_bar`` is a Grashof crank-rocker (l1 + l0 <= l2 + l3, the crank
shortest): its crank can turn full circle without meeting a change point.  No force drives it,
so each start either swings for ever or turns; the reference for each cell is one adaptive
:func:`closedloop.simulate` run (minimal coordinates, DOP853, rtol = atol = 1e-10).
"""

import math

import numpy as np
import pytest

from closedloop import InputError, Minimal, consistent_initial_state, simulate
from closedloop.four_bar import parameter_values
from closedloop.slider_crank import MOTIONS
from closedloop.studies.basin import grid_values, integrate_outcomes, reference_outcome

#: A 6 x 6 grid of crank angles [rad] and rates [rad/s]; both outcomes occur on it.
ANGLES = grid_values(0.0, 2.0 * math.pi, 6)
RATES = grid_values(0.0, 12.0, 6)
T_END = 5.0
FULL_TURN = 2.0 * math.pi


def open_branch_start(system, theta1, rate):
    """A consistent start with the coupler above the line AD (elbow up), from the triangle A-B-D.

    theta2 = angle(D - A) + alpha with cos alpha = (l2^2 + |AD|^2 - l3^2) / (2 l2 |AD|), and
    theta3 = angle(B - D); Newton and (9) then make it exact.
    """
    lengths = parameter_values(system)
    a = lengths["l1"] * np.array([math.cos(theta1), math.sin(theta1)])
    to_d = np.array([lengths["l0"], 0.0]) - a
    distance = math.hypot(*to_d)
    alpha = math.acos((lengths["l2"] ** 2 + distance ** 2 - lengths["l3"] ** 2) / (2 * lengths["l2"] * distance))
    theta2 = math.atan2(to_d[1], to_d[0]) + alpha
    b = a + lengths["l2"] * np.array([math.cos(theta2), math.sin(theta2)])
    theta3 = math.atan2(b[1], b[0] - lengths["l0"])
    return consistent_initial_state(system, [theta1], [rate], [theta2, theta3])


@pytest.fixture(scope="module")
def cells():
    angles, rates = np.meshgrid(ANGLES, RATES)
    return angles.ravel(), rates.ravel()


@pytest.fixture(scope="module")
def batch(four_bar, cells):
    return integrate_outcomes(four_bar, *cells, T_END, initial_state=open_branch_start)


@pytest.fixture(scope="module")
def reference_excursions(four_bar, cells):
    """max |theta1(t) - theta1(0)| of one simulate() run per cell, stopped once past 2 pi + 0.5 rad."""
    limit = FULL_TURN + 0.5
    excursions = []
    for angle, rate in zip(*cells):
        result = simulate(four_bar, open_branch_start(four_bar, angle, rate), T_END, formulation=Minimal(),
                          method="DOP853", rtol=1e-10, atol=1e-10,
                          stop_when=lambda t, s, sd: abs(s[0] - angle) - limit)
        excursions.append(np.max(np.abs(result.coordinate("theta1") - angle)))
    return np.array(excursions)


def test_the_grid_holds_both_outcomes_away_from_the_boundary(reference_excursions):
    """The agreement below is only worth something if both outcomes occur and no cell is a near miss."""
    rotating = reference_excursions >= FULL_TURN
    assert 0.2 < np.mean(rotating) < 0.8
    assert np.min(np.abs(reference_excursions - FULL_TURN)) > 0.3


def test_every_four_bar_cell_gets_the_outcome_of_its_own_simulate_run(batch, reference_excursions):
    expected = (reference_excursions >= FULL_TURN).astype(int)
    np.testing.assert_array_equal(batch.codes, expected)
    swinging = expected == 0
    # both see a swing's peak at their step ends only (0.02 s apart in the batch), so a little short of it
    np.testing.assert_allclose(batch.excursion[swinging], reference_excursions[swinging], rtol=0, atol=0.01)
    assert np.all(batch.excursion[~swinging] >= FULL_TURN)
    assert np.all(batch.decided_at[~swinging] < T_END) and np.all(np.isnan(batch.decided_at[swinging]))
    assert batch.max_constraint_error < 1e-10 and batch.switch_events.sum() == 0      # no switched force


def test_the_per_cell_reference_classifies_the_four_bar_too(four_bar, batch, cells):
    """reference_outcome follows the independent coordinate, whatever its name (theta1 here)."""
    for k in (0, 7, 14, 21, 35):                           # swings and turns, across the grid
        code = reference_outcome(four_bar, cells[0][k], cells[1][k], T_END, initial_state=open_branch_start)
        assert MOTIONS[code] == MOTIONS[batch.codes[k]]
    assert {int(batch.codes[k]) for k in (0, 7, 14, 21, 35)} == {0, 1}


def test_a_system_other_than_the_slider_crank_must_say_how_it_starts(four_bar):
    with pytest.raises(InputError, match=r"initial_state: needed for a system other than the slider-crank"):
        integrate_outcomes(four_bar, [0.0], [1.0], 1.0)


def test_a_start_that_moves_the_independent_coordinate_is_refused(four_bar):
    def shifted(system, theta1, rate):
        return open_branch_start(system, theta1 + 0.1, rate)

    with pytest.raises(InputError, match=r"initial_state: returned q = 0\.1.*must keep them"):
        integrate_outcomes(four_bar, [0.0], [1.0], 1.0, initial_state=shifted)
