"""The paper's data and its four cases: outcomes, the table of readings, the gas force, sticking."""

import math

import numpy as np
import pytest

from closedloop import Minimal, simulate
from closedloop.slider_crank import CASES, classify_motion, gas_force, initial_state
from closedloop.studies.readings import reading_outcomes


@pytest.mark.parametrize("number", sorted(CASES))
def test_the_four_cases_move_as_the_paper_found(slider_crank, number):
    """Oscillation, full rotation, oscillation, full rotation, with the defaults."""
    case = CASES[number]
    result = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 20.0)
    expected = {1: "oscillation", 2: "full rotation", 3: "oscillation", 4: "full rotation"}[number]
    assert classify_motion(result) == expected == case.finding
    turned = np.max(np.abs(result.coordinate("phi") - case.phi0))
    # a clear verdict, not a near miss of 2 pi
    assert (turned > 3 * math.pi) if expected == "full rotation" else (turned < 1.9 * math.pi)


@pytest.fixture(scope="module")
def table():
    return {(row.reading, row.case): row for row in reading_outcomes()}


def test_reading_decimal_opposing_reproduces_the_paper(table):
    assert [table["decimal-opposing", n].motion for n in (1, 2, 3, 4)] == [
        "oscillation", "full rotation", "oscillation", "full rotation"]
    assert all(table["decimal-opposing", n].runaway_at is None for n in CASES)


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


def test_gas_force_matches_the_printed_formula_and_is_continuous():
    # starts at zero up to the print's rounding: 282.857/4.5 - 62.857 = -1.1e-4 N (1980/7 and 440/7 rounded)
    assert gas_force(1.5, 1.0) == pytest.approx(-282.857 / 4.5 + 62.857, abs=1e-12)
    assert abs(gas_force(1.5, 1.0)) < 2e-4
    below, above = gas_force(5.0 - 1e-12, 1.0), gas_force(5.0 + 1e-12, 1.0)
    assert below == pytest.approx(-220.0, abs=1e-6) and above == pytest.approx(-220.0, abs=1e-6)
    assert gas_force(5.5, 1.0) == pytest.approx(0.0, abs=1e-12)
    assert gas_force(3.0, 1.0) == pytest.approx(-282.857 / 3.0 + 62.857)
    assert gas_force(3.0, 0.0) == 0.0 and gas_force(3.0, -1.0) == 0.0      # only for x_C' > 0
    assert gas_force(3.0, 1.0, "thousands-opposing") == pytest.approx(1000 * gas_force(3.0, 1.0))


def test_gas_force_enters_with_the_readings_sign(slider_crank):
    from closedloop.slider_crank import slider_crank_system

    s, sd = np.array([2.0, 3.0, 3.0]), np.array([0.0, 0.0, 1.0])
    opposing = slider_crank.force(0.0, s, sd, (True, False))
    printed = slider_crank_system(reading="decimal-as-printed").force(0.0, s, sd, (True, False))
    assert opposing[2] == pytest.approx(gas_force(3.0, 1.0)) and opposing[2] < 0
    assert printed[2] == pytest.approx(-gas_force(3.0, 1.0))
    assert opposing[0] == opposing[1] == 0.0


@pytest.mark.parametrize("number, expected", [(3, 28.4), (1, 37.8)])
def test_long_runs_stick_where_the_notes_measured_and_do_not_hang(slider_crank, number, expected):
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


def test_a_stuck_slider_is_released_where_the_holding_force_reaches_its_limit():
    """A torque ripple large enough to free the slider: stick, release, and carry on.

    At the release the slider is at rest, and the acceleration of x_C on one of the two
    branches (gas force off, or on) passes through zero: the holding force has reached 0
    or F_gas(x). This is computed here from (12) at the held state, independently of the
    sticking rule's own root finding.
    """
    from closedloop.slider_crank import OMEGA, GasForce, SliderCrankParameters, SliderCrankSystem, get_reading

    reading, parameters = get_reading("thousands-opposing"), SliderCrankParameters()
    values = dict(parameters.as_dict(), torque_mean=reading.torque_mean, torque_ripple=3e5, omega=OMEGA)
    system = SliderCrankSystem(parameters, reading, values, GasForce(reading))
    result = simulate(system, initial_state(system, math.pi, 1.0), 5.0)
    released = [e for e in result.switch_events if e.action == "released"]
    assert released and result.t[-1] == 5.0
    start, end = result.sticking_intervals[0]
    assert end == pytest.approx(released[0].t) and end - start > 0.05
    held = result.s[:, np.searchsorted(result.t, start, side="right")]
    rest = np.zeros(3)
    x_acc = [system.constrained_accelerations(end, held, rest, (on, held[2] > 5))[0][2] for on in (False, True)]
    before = [system.constrained_accelerations(start, held, rest, (on, held[2] > 5))[0][2] for on in (False, True)]
    assert min(abs(a) for a in x_acc) < 1e-6 * max(abs(a) for a in before)
    moving = result.t > end + 0.01
    assert np.max(np.abs(result.sd[2, moving])) > 0.01           # it does move again
    assert result.max_constraint_error < 1e-5


def test_output_times_may_end_before_t_end(slider_crank):
    case = CASES[2]
    result = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 20.0, t_eval=[0.0, 0.5])
    full = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 0.5, t_eval=[0.5])
    assert list(result.t) == [0.0, 0.5]
    assert np.allclose(result.s[:, 1], full.s[:, 0], atol=1e-7)


def test_the_old_home_of_reading_outcomes_warns_and_gives_the_study():
    """Readers' code of 0.1 imported the study from the mechanism; it still works, with a warning."""
    import closedloop.slider_crank as slider_crank

    with pytest.warns(DeprecationWarning, match=r"moved to closedloop\.studies\.readings"):
        old = slider_crank.reading_outcomes
    assert old is reading_outcomes
    assert "reading_outcomes" not in slider_crank.__all__ and "ReadingOutcome" not in slider_crank.__all__
    with pytest.raises(AttributeError, match="no_such_name"):
        slider_crank.no_such_name
