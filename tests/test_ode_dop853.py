"""The compiled DOP853 backend ("ode.dop853"): events, outputs, errors, agreement with solve_ivp."""

import math

import numpy as np
import pytest
from scipy.integrate import DOP853, ode, solve_ivp

from closedloop import InputError, IntegrationError, Minimal, simulate
from closedloop.formulations import ClosedForm
from closedloop.simulation import dop853, dop853_dense
from closedloop.simulation.dop853 import REJECTION_FACTOR, STEP_CONTROL_BETA, Calls, _counting, integrate_segment
from closedloop.simulation.dop853_dense import HeldStep, continuous_extension, interpolate, step_stages
from closedloop.slider_crank import get_case, initial_state


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


def test_direction_filters_crossings_and_outputs_end_before_the_switch():
    # Rising crossings of cos t only: the first is at 3 pi / 2.
    outputs = np.array([0.0, 0.5, 1.0, 4.0, 5.0])
    seg = integrate_segment(oscillator, 0.0, np.array([1.0, 0.0]), 10.0, rtol=1e-11, atol=1e-11,
                            switching=lambda t, y: [y[0]], directions=[1.0], outputs=outputs)
    assert abs(seg.t_stop - 1.5 * math.pi) < 1e-10
    assert list(seg.t) == [0.0, 0.5, 1.0, 4.0]            # 5.0 lies beyond the stop
    assert np.allclose(seg.y[0], np.cos(seg.t), atol=1e-10)


def test_a_rejected_step_is_retried_at_no_less_than_the_rejection_factor_of_its_size():
    # A first step of 2 s on cos t at rtol 1e-11 is rejected, again and again: each attempt ends with
    # its 12th stage at t0 + h (c_12 = 1), the calls 11, 22, ... after f(t0).  scipy's default fac1 = 0.3
    # retried at 0.3 h whatever the error (its C translation), which this factor replaces.
    times = []

    def recorded(t, y):
        times.append(t)
        return oscillator(t, y)

    seg = integrate_segment(recorded, 0.0, np.array([1.0, 0.0]), 10.0, rtol=1e-11, atol=1e-11,
                            switching=lambda t, y: [], directions=[], first_step=2.0)
    first = seg.steps[0]
    attempts = [t for t in times[11::11] if t >= first]
    attempts = attempts[:attempts.index(first) + 1]        # from the first attempt to the accepted one
    assert attempts[0] == 2.0 and len(attempts) >= 3       # rejected at least twice
    ratios = np.array(attempts[1:]) / np.array(attempts[:-1])
    assert REJECTION_FACTOR == 0.6
    assert ratios.min() >= REJECTION_FACTOR * (1 - 1e-12)
    assert ratios.max() < 1.0


def test_its_steps_are_those_of_scipys_ode_with_the_same_rejection_factor_and_beta():
    # The settings reach the code: scipy's own wrapper, given the two that differ from its defaults,
    # takes step for step the same steps (and beta = 0, scipy's default, takes others).
    def steps_of_ode(beta):
        ends = []
        solver = ode(oscillator).set_integrator("dop853", rtol=1e-10, atol=1e-10, dfactor=REJECTION_FACTOR,
                                                 beta=beta, first_step=0.5)
        solver.set_solout(lambda t, y: ends.append(t))
        solver.set_initial_value([1.0, 0.0], 0.0)
        solver.integrate(30.0)
        return np.diff(ends)

    seg = integrate_segment(oscillator, 0.0, np.array([1.0, 0.0]), 30.0, rtol=1e-10, atol=1e-10,
                            switching=lambda t, y: [], directions=[], first_step=0.5)
    assert STEP_CONTROL_BETA == 0.04
    assert np.array_equal(np.array(seg.steps), steps_of_ode(STEP_CONTROL_BETA))
    plain = steps_of_ode(0.0)
    assert plain.size != len(seg.steps) or not np.array_equal(plain, seg.steps)


def test_the_stabilised_step_control_costs_fewer_evaluations_for_no_larger_errors(slider_crank, monkeypatch):
    # The measurement behind STEP_CONTROL_BETA, on a smaller sample: the paper's four cases over 20 s at
    # three tolerances, errors at t = 20 s against minimal coordinates at 1e-13.
    tolerances = (1e-8, 1e-9, 1e-10)
    states = [initial_state(slider_crank, get_case(n).phi0, get_case(n).dphi0) for n in (1, 2, 3, 4)]
    exact = [simulate(slider_crank, state, 20.0, formulation=Minimal(), method="DOP853", rtol=1e-13,
                      atol=1e-13, t_eval=(20.0,)) for state in states]

    def work_and_errors():
        nfev, errors = 0, []
        for state, reference in zip(states, exact):
            for tol in tolerances:
                run = simulate(slider_crank, state, 20.0, formulation=ClosedForm(1, 1), method="ode.dop853",
                               rtol=tol, atol=tol, t_eval=(20.0,))
                nfev += run.nfev
                errors.append(max(np.max(np.abs(run.s - reference.s)), np.max(np.abs(run.sd - reference.sd)))
                              / tol)
        return nfev, np.array(errors)

    nfev, errors = work_and_errors()
    monkeypatch.setattr(dop853, "STEP_CONTROL_BETA", 0.0)
    nfev_plain, errors_plain = work_and_errors()
    assert nfev < 0.97 * nfev_plain
    assert errors.max() <= errors_plain.max()
    assert np.mean(np.log10(errors)) <= np.mean(np.log10(errors_plain))


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
    with pytest.raises(IntegrationError, match=r"ode\.dop853 failed at t = [0-9.e-]+ s: more step attempts .* nsteps = 5 allows"):
        simulate(slider_crank, state, 20.0, formulation=ClosedForm(), method="ode.dop853", nsteps=5)


def test_solve_ivp_options_it_does_not_take_are_refused_before_integrating(slider_crank):
    state = initial_state(slider_crank, math.pi / 2, 1.0)
    with pytest.raises(InputError, match="min_step"):
        simulate(slider_crank, state, 1.0, formulation=ClosedForm(), method="ode.dop853", min_step=1e-3)


def test_it_runs_the_formulations_without_a_partition_too(slider_crank):
    """The branch guard at det Phi_z = 0 runs on the watch of the accepted steps, which needs no dense output:
    Augmented, Baumgarte and NullSpace run on the compiled code, the same motion as on solve_ivp's DOP853."""
    from closedloop import Augmented, Baumgarte, NullSpace

    state = initial_state(slider_crank, math.pi / 2, 1.0)
    for formulation in (Augmented(), Baumgarte(), NullSpace()):
        settings = dict(formulation=formulation, rtol=1e-10, atol=1e-10, t_eval=[2.0])
        compiled = simulate(slider_crank, state, 2.0, method="ode.dop853", **settings)
        reference = simulate(slider_crank, state, 2.0, method="DOP853", **settings)
        assert np.max(np.abs(compiled.s[:, -1] - reference.s[:, -1])) < 1e-7
        assert [e.action for e in compiled.switch_events] == [e.action for e in reference.switch_events]


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


# -- outputs: DOP853's continuous extension inside the compiled code's steps ------------------------------

def pendulum_rhs(t, y):
    return np.array([y[1], -math.sin(y[0]) + 0.3 * math.cos(2.0 * t)])


def test_the_continuous_extension_is_scipys_dop853_dense_output_to_round_off():
    solver = DOP853(pendulum_rhs, 0.0, np.array([1.0, 0.0]), 10.0, rtol=1e-6, atol=1e-6)
    for _ in range(3):
        solver.step()
    ta, ya, tb, yb = solver.t_old, solver.dense_output().y_old, solver.t, solver.y
    x = np.linspace(0.0, 1.0, 7)
    expected = solver.dense_output()(ta + x * (tb - ta))
    stages = step_stages(pendulum_rhs, ta, ya, tb - ta, pendulum_rhs(ta, ya), t_end=tb, y_end=yb)
    ours = interpolate(continuous_extension(pendulum_rhs, ta, ya, tb, yb, stages), ya, x)
    assert np.max(np.abs(ours - expected)) < 1e-14
    assert np.max(np.abs(ours[:, -1] - yb)) < 1e-15 and np.max(np.abs(ours[:, 0] - ya)) < 1e-15


def test_stages_recomputed_from_the_step_start_give_the_compiled_codes_step_end_to_round_off():
    ends = []

    def solout(t, y):
        ends.append((t, y.copy()))

    solver = ode(pendulum_rhs).set_integrator("dop853", rtol=1e-8, atol=1e-8)
    solver.set_solout(solout)
    solver.set_initial_value([1.0, 0.0], 0.0)
    solver.integrate(10.0)
    assert len(ends) > 20
    eps = np.finfo(float).eps
    for (ta, ya), (tb, yb) in zip(ends, ends[1:]):
        h = tb - ta
        stages = step_stages(pendulum_rhs, ta, ya, h, pendulum_rhs(ta, ya))
        rebuilt = ya + h * (DOP853.B @ stages[:12])
        # in units of the round-off of ya + h sum b_i k_i: a wrong stage or coefficient would be ~1e8 units
        units = np.abs(rebuilt - yb) / (eps * (np.abs(ya) + abs(h) * (np.abs(DOP853.B) @ np.abs(stages[:12]))))
        assert units.max() < 64


def steps_holding(outputs, t0, steps):
    """How many of the steps (sizes ``steps``, one after another from t0) hold an output strictly inside."""
    ends = t0 + np.cumsum(steps)
    starts = np.append(t0, ends[:-1])
    return int(sum(np.any((outputs > a) & (outputs < b)) for a, b in zip(starts, ends)))


def test_outputs_inside_steps_and_before_a_switch_follow_the_exact_solution():
    # y = cos t falls through zero at pi/2; 1001 output times, of which those before pi/2 come out.
    outputs = np.linspace(0.0, 10.0, 1001)
    options = dict(rtol=1e-10, atol=1e-10, switching=lambda t, y: [y[0]], directions=[-1.0])
    plain = integrate_segment(oscillator, 0.0, np.array([1.0, 0.0]), 10.0, **options)
    seg = integrate_segment(oscillator, 0.0, np.array([1.0, 0.0]), 10.0, outputs=outputs, **options)
    assert list(seg.t) == list(outputs[outputs < math.pi / 2])
    assert seg.steps == plain.steps and seg.t_stop == plain.t_stop
    assert np.array_equal(seg.y_stop, plain.y_stop)
    # The 7th-order extension's error is of the order of the tolerance (3.4e-10 at 1e-10), as that of
    # solve_ivp's DOP853, whose dense output it is; the step ends are far better (2e-11).
    output_error = np.max(np.abs(seg.y[0] - np.cos(seg.t)))
    theirs = solve_ivp(oscillator, (0.0, 10.0), [1.0, 0.0], method="DOP853", rtol=1e-10, atol=1e-10, t_eval=outputs)
    assert output_error < 5e-10 and output_error < 1.5 * np.max(np.abs(theirs.y[0] - np.cos(outputs)))
    assert np.max(np.abs(plain.y[0] - np.cos(plain.t))) < 3e-11
    # three extra right-hand sides per step holding an output (the crossing step too): the stages are the code's
    assert seg.nfev - plain.nfev == 3 * steps_holding(seg.t, 0.0, plain.steps)


def test_outputs_at_step_ends_cost_nothing_and_are_the_codes_states():
    options = dict(rtol=1e-10, atol=1e-10, switching=lambda t, y: [], directions=[])
    plain = integrate_segment(oscillator, 0.0, np.array([1.0, 0.0]), 5.0, **options)
    ends = plain.t[[0, 3, -1]]                              # the start, a step end, t_end
    seg = integrate_segment(oscillator, 0.0, np.array([1.0, 0.0]), 5.0, outputs=ends, **options)
    assert seg.nfev == plain.nfev
    assert np.array_equal(seg.t, ends) and np.array_equal(seg.y, plain.y[:, [0, 3, -1]])


def test_a_right_hand_side_that_reuses_its_array_is_recorded_by_value():
    buffer = np.empty(2)

    def reusing(t, y):
        buffer[0], buffer[1] = y[1], -y[0]
        return buffer

    outputs = np.linspace(0.0, 5.0, 51)
    options = dict(rtol=1e-10, atol=1e-10, switching=lambda t, y: [], directions=[])
    plain = integrate_segment(reusing, 0.0, np.array([1.0, 0.0]), 5.0, **options)
    seg = integrate_segment(reusing, 0.0, np.array([1.0, 0.0]), 5.0, outputs=outputs, **options)
    recorded = integrate_segment(oscillator, 0.0, np.array([1.0, 0.0]), 5.0, outputs=outputs, **options)
    assert np.max(np.abs(seg.y - recorded.y)) < 1e-14
    # each call's values were copied when it returned: the stages pass the check, 3 more per step
    assert seg.nfev - plain.nfev == 3 * steps_holding(outputs, 0.0, plain.steps)


@pytest.mark.parametrize("recorded", ["missing", "wrong"])
def test_a_step_whose_recorded_stages_are_missing_or_wrong_is_recomputed(recorded):
    # "missing": some of the step's calls were not recorded (recording was off, or a call did not give n
    # values); "wrong": recorded stages that do not rebuild the code's step end (here the stages of another
    # step).  Either way the 13 stages are recomputed from the step's start and checked: 13 + 3 calls.
    options = dict(rtol=1e-10, atol=1e-10, switching=lambda t, y: [], directions=[])
    plain = integrate_segment(oscillator, 0.0, np.array([1.0, 0.0]), 5.0, **options)
    ta, tb = plain.step_times[2], plain.step_times[3]
    ya, yb = plain.step_ends[:, 2], plain.step_ends[:, 3]
    times = np.linspace(ta, tb, 7)[1:-1]
    if recorded == "missing":
        step, stages = HeldStep(ta, ya, tb, yb, False, math.nan, math.nan, 0, times.size), [0.0] * 26
    else:
        t1, y1 = plain.step_times[1], plain.step_ends[:, 1]
        other = step_stages(oscillator, t1, y1, ta - t1, oscillator(t1, y1), t_end=ta, y_end=ya)[:13]
        first = ta + DOP853.C[1] * (tb - ta)
        step, stages = HeldStep(ta, ya, tb, yb, True, first, tb, 0, times.size), other.ravel().tolist()
    calls = []

    def counted(t, y):
        calls.append(t)
        return oscillator(t, y)

    states = np.empty((2, times.size))
    dop853_dense.evaluate_held_steps(counted, [step], stages, times, states)
    assert len(calls) == 16
    assert np.max(np.abs(states - np.vstack((np.cos(times), -np.sin(times))))) < 1e-9


@pytest.fixture(scope="module")
def case_2_runs(slider_crank):
    """Case 2 over 1 s with ode.dop853: no outputs, 10 001 and 50 001 output times, and a tight reference."""
    state = initial_state(slider_crank, math.pi / 2, 1.0)
    options = dict(formulation=ClosedForm(), method="ode.dop853", rtol=1e-9, atol=1e-9)
    grid = np.linspace(0.0, 1.0, 10_001)
    return dict(
        none=simulate(slider_crank, state, 1.0, **options),
        grid=simulate(slider_crank, state, 1.0, t_eval=grid, **options),
        fine=simulate(slider_crank, state, 1.0, t_eval=np.linspace(0.0, 1.0, 50_001), **options),
        reference=simulate(slider_crank, state, 1.0, formulation=Minimal(), method="DOP853", rtol=1e-13,
                           atol=1e-13, t_eval=grid))


def test_an_output_grid_changes_neither_the_steps_nor_the_end_state(case_2_runs):
    none, grid = case_2_runs["none"], case_2_runs["grid"]
    assert grid.t.size == 10_001 and none.n_steps < 100
    assert np.array_equal(grid.step_sizes, none.step_sizes)
    assert grid.t[-1] == none.t[-1] == 1.0
    assert np.max(np.abs(grid.s[:, -1] - none.s[:, -1])) < 1e-13
    assert np.max(np.abs(grid.sd[:, -1] - none.sd[:, -1])) < 1e-13


def test_an_output_grid_costs_three_evaluations_per_step(case_2_runs):
    none, grid, fine = case_2_runs["none"], case_2_runs["grid"], case_2_runs["fine"]
    assert grid.nfev == none.nfev + 3 * steps_holding(grid.t, 0.0, none.step_sizes)
    assert fine.nfev == grid.nfev                           # 5 times the outputs, the same cost
    assert grid.nfev <= 1.5 * none.nfev


def test_outputs_on_a_grid_are_as_accurate_as_the_tolerance(case_2_runs):
    grid, reference = case_2_runs["grid"], case_2_runs["reference"]
    state, ref = np.vstack((grid.s, grid.sd)), np.vstack((reference.s, reference.sd))
    assert np.max(np.abs(state - ref) / (1e-9 + 1e-9 * np.abs(ref))) < 1.0


def test_one_output_time_in_a_long_segment_costs_its_step_three_evaluations_and_nothing_per_call():
    # One output time among some 80 steps: only the steps just before it record their calls, and the
    # output is the one a dense grid through the same time gives, to the last unit (the two sum the
    # extension's seven terms with different matrix products: one column, or many).
    options = dict(rtol=1e-10, atol=1e-10, switching=lambda t, y: [], directions=[])
    plain = integrate_segment(oscillator, 0.0, np.array([1.0, 0.0]), 20.0, **options)
    one = integrate_segment(oscillator, 0.0, np.array([1.0, 0.0]), 20.0, outputs=np.array([13.3]), **options)
    grid = np.sort(np.append(np.linspace(0.0, 20.0, 401), 13.3))
    dense = integrate_segment(oscillator, 0.0, np.array([1.0, 0.0]), 20.0, outputs=grid, **options)
    assert len(plain.steps) > 50 and one.steps == plain.steps
    assert one.nfev == plain.nfev + 3                       # the stages were recorded, not recomputed (+16)
    assert one.t.tolist() == [13.3]
    same = dense.y[:, np.searchsorted(grid, 13.3)]
    assert np.all(np.abs(one.y[:, 0] - same) <= np.spacing(np.abs(same)))
    assert abs(one.y[0, 0] - math.cos(13.3)) < 1e-9


@pytest.mark.parametrize("t_end, count", [(20.0, 30_001), (1.0, 50_001)])
def test_outputs_evaluated_together_are_those_of_each_step_alone(t_end, count):
    # All the steps' outputs are evaluated at once, their basis in groups of steps: over 20 s groups
    # span several steps (some 370 outputs each); over 1 s each step holds more than a group's outputs
    # (some 2500).  Each output must be the extension of its own step, computed step by step from
    # recomputed stages (to round-off: the recorded stages are the code's, whose arguments it sums
    # in its own order, and the two sum the extension's terms with different matrix products).
    options = dict(rtol=1e-10, atol=1e-10, switching=lambda t, y: [], directions=[])
    plain = integrate_segment(pendulum_rhs, 0.0, np.array([1.0, 0.0]), t_end, **options)
    outputs = np.linspace(0.0, t_end, count)
    seg = integrate_segment(pendulum_rhs, 0.0, np.array([1.0, 0.0]), t_end, outputs=outputs, **options)
    assert np.array_equal(seg.t, outputs)
    ends = plain.step_times
    step = np.clip(np.searchsorted(ends, outputs, side="left") - 1, 0, ends.size - 2)
    expected = np.empty_like(seg.y)
    for k in np.unique(step):
        ta, tb, ya, yb = ends[k], ends[k + 1], plain.step_ends[:, k], plain.step_ends[:, k + 1]
        stages = step_stages(pendulum_rhs, ta, ya, tb - ta, pendulum_rhs(ta, ya), t_end=tb, y_end=yb)
        at = step == k
        expected[:, at] = interpolate(continuous_extension(pendulum_rhs, ta, ya, tb, yb, stages), ya,
                                      (outputs[at] - ta) / (tb - ta))
    on_ends = np.isin(outputs, ends)
    expected[:, on_ends] = plain.step_ends[:, np.searchsorted(ends, outputs[on_ends])]
    assert np.max(np.abs(seg.y - expected)) < 32 * np.finfo(float).eps * np.max(np.abs(expected))


def test_the_counting_right_hand_side_records_its_calls_only_while_asked():
    calls = Calls()
    counted, evaluations, record = _counting(oscillator, math.inf, [], calls)
    counted(0.0, np.array([1.0, 0.0]))
    record(False)
    counted(0.5, np.array([1.0, 0.0]))
    record(True)
    counted(1.0, np.array([0.0, 1.0]))
    assert evaluations() == 3
    assert calls.times == [0.0, 1.0] and calls.values == [0.0, -1.0, 1.0, 0.0]
