"""The compiled DOP853 backend ("ode.dop853"): events, outputs, errors, agreement with solve_ivp."""

import math

import numpy as np
import pytest

from closedloop import InputError, IntegrationError, Minimal, simulate
from closedloop.formulations import ClosedForm
from closedloop.simulation.dop853 import integrate_segment
from closedloop.slider_crank import initial_state


def oscillator(t, y):
    return [y[1], -y[0]]


def test_a_zero_crossing_is_located_to_round_off_on_the_integrated_solution():
    # y = cos t: y falls through zero at t = pi/2 with y' = -1 there.
    seg = integrate_segment(oscillator, 0.0, np.array([1.0, 0.0]), 10.0, rtol=1e-11, atol=1e-11,
                            switching=lambda t, y: [y[0]], directions=[-1.0])
    assert seg.event == 0
    assert abs(seg.y_stop[0]) < 1e-15                      # the switching function is zero there
    assert abs(seg.t_stop - math.pi / 2) < 1e-10           # and that is pi/2 up to the global error
    assert abs(seg.y_stop[1] + 1.0) < 1e-10
    assert seg.t[-1] == seg.t_stop and np.all(np.diff(seg.t) > 0)


def test_direction_filters_crossings_and_outputs_are_exact_step_ends():
    # Rising crossings of cos t only: the first is at 3 pi / 2.
    outputs = np.array([0.0, 0.5, 1.0, 4.0, 5.0])
    seg = integrate_segment(oscillator, 0.0, np.array([1.0, 0.0]), 10.0, rtol=1e-11, atol=1e-11,
                            switching=lambda t, y: [y[0]], directions=[1.0], outputs=outputs)
    assert abs(seg.t_stop - 1.5 * math.pi) < 1e-10
    assert list(seg.t) == [0.0, 0.5, 1.0, 4.0]            # 5.0 lies beyond the stop
    assert np.allclose(seg.y[0], np.cos(seg.t), atol=1e-10)


def test_an_exception_in_the_right_hand_side_comes_out_instead_of_a_hang():
    def failing(t, y):
        if t > 0.5:
            raise ValueError("boom at the right-hand side")
        return oscillator(t, y)

    with pytest.raises(ValueError, match="boom"):
        integrate_segment(failing, 0.0, np.array([1.0, 0.0]), 10.0, rtol=1e-9, atol=1e-9,
                          switching=lambda t, y: [], directions=[])


def test_a_step_budget_that_runs_out_names_the_time(slider_crank):
    state = initial_state(slider_crank, math.pi / 2, 1.0)
    with pytest.raises(IntegrationError, match=r"ode\.dop853 failed at t = [0-9.e-]+ s: more steps"):
        simulate(slider_crank, state, 20.0, formulation=ClosedForm(), method="ode.dop853", nsteps=5)


def test_solve_ivp_options_it_does_not_take_are_refused_before_integrating(slider_crank):
    state = initial_state(slider_crank, math.pi / 2, 1.0)
    with pytest.raises(InputError, match="min_step"):
        simulate(slider_crank, state, 1.0, formulation=ClosedForm(), method="ode.dop853", min_step=1e-3)


def test_formulations_that_need_the_branch_guard_are_refused(slider_crank):
    from closedloop import Augmented, Baumgarte, NullSpace

    state = initial_state(slider_crank, math.pi / 2, 1.0)
    for formulation in (Augmented(), Baumgarte(), NullSpace()):
        with pytest.raises(InputError, match="no dense output for the branch guard"):
            simulate(slider_crank, state, 1.0, formulation=formulation, method="ode.dop853")


@pytest.mark.parametrize("number, phi0, dphi0", [(2, math.pi / 2, 1.0), (3, math.pi, 0.5)])
def test_it_agrees_with_the_minimal_reference_and_switches_where_solve_ivp_does(slider_crank, number, phi0,
                                                                                 dphi0):
    state = initial_state(slider_crank, phi0, dphi0)
    times = np.linspace(0.0, 10.0, 6)
    reference = simulate(slider_crank, state, 10.0, formulation=Minimal(), method="DOP853", rtol=1e-12,
                         atol=1e-12, t_eval=times)
    fast = simulate(slider_crank, state, 10.0, formulation=ClosedForm(1, 1), method="ode.dop853", rtol=1e-10,
                    atol=1e-10, t_eval=times)
    assert np.max(np.abs(fast.s - reference.s)) < 1e-8
    assert np.max(np.abs(fast.sd - reference.sd)) < 1e-8
    assert [e.switch for e in fast.switch_events] == [e.switch for e in reference.switch_events]
    assert np.max(np.abs(np.array([e.t for e in fast.switch_events])
                         - np.array([e.t for e in reference.switch_events]))) < 1e-8


def test_case_3_sticks_at_the_same_time_as_with_solve_ivp(slider_crank):
    state = initial_state(slider_crank, math.pi, 0.5)
    fast = simulate(slider_crank, state, 32.0, formulation=ClosedForm(5, 5), method="ode.dop853", rtol=1e-10,
                    atol=1e-10)
    slow = simulate(slider_crank, state, 32.0, formulation=ClosedForm(5, 5), method="DOP853", rtol=1e-10,
                    atol=1e-10)
    assert len(fast.sticking_intervals) == len(slow.sticking_intervals) == 1
    assert abs(fast.sticking_intervals[0][0] - slow.sticking_intervals[0][0]) < 1e-6
    assert abs(fast.sticking_intervals[0][0] - 28.446) < 1e-3
