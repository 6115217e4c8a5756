"""The paper's four cases: how each moves, how the readings of the print change that, and when cases 1 and 3 stick.

Each fact has one test here: the four outcomes (by simulate, the basin map's batch integrator, its
per-cell reference and the readings study), and the sticking times 28.4 s and 37.8 s (by simulate
and the batch integrator).
"""

import math

import numpy as np
import pytest

from closedloop import InputError, Minimal, simulate
from closedloop.slider_crank import CASES, MOTIONS, classify_motion, initial_state, motion_codes
from closedloop.studies.basin import basin_map, grid_values, integrate_outcomes, reference_outcome
from closedloop.studies.readings import reading_outcomes

#: The paper's findings, typed from section 4.
PAPER = {1: "oscillation", 2: "full rotation", 3: "oscillation", 4: "full rotation"}


@pytest.fixture(scope="module")
def table():
    """The readings study: every reading of the print, every case."""
    return {(row.reading, row.case): row for row in reading_outcomes()}


@pytest.fixture(scope="module")
def batch(slider_crank):
    """The four cases through the basin map's batch integrator, 20 s."""
    return integrate_outcomes(slider_crank, [case.phi0 for case in CASES.values()],
                              [case.dphi0 for case in CASES.values()], 20.0)


@pytest.fixture(scope="module")
def whole_map():
    """A 4 x 6 basin map of [0, 2 pi) x [0, 3] rad/s, 20 s: it holds all four cases."""
    return basin_map(grid_values(0.0, 2 * math.pi, 4), grid_values(0.0, 3.0, 6), 20.0)


@pytest.mark.parametrize("number", sorted(CASES))
def test_the_four_cases_move_as_the_paper_found(slider_crank, table, batch, whole_map, number):
    """Oscillation, full rotation, oscillation, full rotation, with the defaults: simulate and
    classify_motion, the batch integrator, the map, the per-cell reference and the readings study agree."""
    case = CASES[number]
    result = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 20.0)
    assert classify_motion(result) == classify_motion(result, case.phi0) == PAPER[number] == case.finding
    turned = np.max(np.abs(result.coordinate("phi") - case.phi0))
    # a clear verdict, not a near miss of 2 pi
    assert (turned > 3 * math.pi) if PAPER[number] == "full rotation" else (turned < 1.9 * math.pi)
    code = batch.codes[list(CASES).index(number)]
    assert MOTIONS[code] == case.finding
    assert MOTIONS[whole_map.outcome_at(case.phi0, case.dphi0)] == case.finding
    assert reference_outcome(slider_crank, case.phi0, case.dphi0) == code
    assert table["decimal-opposing", number].motion == case.finding
    assert table["decimal-opposing", number].runaway_at is None


def test_classify_motion_refuses_a_start_angle_that_is_not_a_number(slider_crank):
    state = initial_state(slider_crank, CASES[2].phi0, CASES[2].dphi0)
    result = simulate(slider_crank, state, 0.2, method="DOP853", rtol=1e-8, atol=1e-8)
    with pytest.raises(InputError, match=r"^phi0: must be a finite number"):
        classify_motion(result, "x")                   # was a TypeError from numpy


def test_motion_codes_is_the_rule_of_classify_motion():
    assert list(motion_codes([0.0, 2 * math.pi - 1e-9, 2 * math.pi, 7.0])) == [0, 0, 1, 1]
    assert MOTIONS[motion_codes(2 * math.pi)] == "full rotation"


def test_reading_decimal_as_printed_makes_all_four_rotate(table):
    assert all(table["decimal-as-printed", n].motion == "full rotation" for n in CASES)


def test_reading_thousands_opposing_sticks_at_once(table):
    for n in CASES:
        row = table["thousands-opposing", n]
        assert row.stuck_at is not None and row.stuck_at < 0.5      # within half a second
        assert row.motion == "oscillation" and row.final_speed == 0.0


def test_reading_thousands_as_printed_spins_up_without_bound(table):
    for n in CASES:
        row = table["thousands-as-printed", n]
        assert row.runaway_at is not None and row.runaway_at < 2.0  # 100 rad/s within 2 s
        assert row.motion == "full rotation"


@pytest.mark.parametrize("number, expected", [(3, 28.4), (1, 37.8)])
def test_long_runs_stick_where_the_notes_measured_and_do_not_hang(slider_crank, number, expected):
    """Cases 3 and 1 stick mid-stroke after 20 s (NOTES.md) and stay stuck: simulate over 60 s,
    and the sticking rule of the batch integrator over 40 s."""
    case = CASES[number]
    result = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 60.0,
                      formulation=Minimal(), method="DOP853", rtol=1e-9, atol=1e-9)
    start, end = result.sticking_intervals[0]
    assert start == pytest.approx(expected, abs=0.1)
    assert end == 60.0
    assert result.nfev < 20000                               # no chattering on the switch
    stuck = result.t > start
    assert np.all(result.sd[:, stuck] == 0.0)
    assert 1.5 < result.s[2, -1] < 5.5                        # held mid-stroke, not at a dead centre
    batch = integrate_outcomes(slider_crank, [case.phi0], [case.dphi0], 40.0)
    assert batch.stuck_at[0] == pytest.approx(expected, abs=0.1)
    assert np.isnan(batch.released_at[0]) and batch.final_dphi[0] == 0.0
