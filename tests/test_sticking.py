"""Switching, sticking and release of the slider: events against a naive if-statement, tolerance
independence, the evaluation cap, a slider held to any t_end, and its release by the holding force.

The notes' sticking times of cases 3 and 1 (28.4 s, 37.8 s) have their home in test_paper_cases.py;
the tests here compare runs with each other (tolerances, switching rules, t_end).
"""

import math

import numpy as np
import pytest

from closedloop import Baumgarte, InitialState, InputError, IntegrationError, Minimal, simulate
from closedloop.slider_crank import CASES, get_case, initial_state

LONG = 200.0


@pytest.fixture(scope="module")
def case3_runs(slider_crank):
    case = CASES[3]
    state = initial_state(slider_crank, case.phi0, case.dphi0)
    runs = {rtol: simulate(slider_crank, state, LONG, formulation=Baumgarte(10, 10), method="DOP853",
                           rtol=rtol, atol=rtol, t_eval=np.linspace(0, LONG, 401), sticking_resolution=0.05)
            for rtol in (1e-6, 1e-9)}
    return state, runs


def test_case3_sticks_for_good_at_the_same_time_and_place_for_every_tolerance(case3_runs):
    _, runs = case3_runs
    loose, tight = runs[1e-6], runs[1e-9]
    for run in (loose, tight):
        assert len(run.sticking_intervals) == 1 and run.sticking_intervals[0][1] == LONG
        assert run.switch_events[-1].action == "stuck"
    assert abs(loose.sticking_intervals[0][0] - tight.sticking_intervals[0][0]) < 1e-4
    assert np.max(np.abs(loose.s[:, -1] - tight.s[:, -1])) < 1e-6
    assert np.all(tight.sd[:, -1] == 0.0)


def test_sticking_time_agrees_with_minimal_coordinates_and_the_earlier_measurement(slider_crank, case3_runs):
    """Minimal coordinates (Newton on z, no Baumgarte) are an independent formulation; NOTES.md measured 28.4 s."""
    state, runs = case3_runs
    reference = simulate(slider_crank, state, 30.0, formulation=Minimal(), method="DOP853", rtol=1e-10, atol=1e-10,
                         t_eval=[30.0])
    assert abs(reference.sticking_intervals[0][0] - runs[1e-9].sticking_intervals[0][0]) < 1e-5
    assert abs(reference.s[0, -1] - runs[1e-9].s[0, -1]) < 1e-7
    assert 28.4 < reference.sticking_intervals[0][0] < 28.5
    # while stuck, the slider rests between the gas-force branches: on the outward stroke, x' = 0
    assert 1.5 < reference.s[2, -1] < 5.5


def test_naive_switching_chatters_and_is_stopped_by_the_evaluation_cap(slider_crank, case3_runs):
    _, runs = case3_runs
    tight = runs[1e-9]
    k = np.searchsorted(tight.t, 28.0)                      # half a second before the slider sticks
    state = InitialState(tight.s[:, k], tight.sd[:, k])
    events = simulate(slider_crank, state, LONG, t_start=tight.t[k], formulation=Baumgarte(10, 10),
                      method="DOP853", rtol=1e-9, atol=1e-9, sticking_resolution=0.05)
    assert events.nfev < 2_000
    with pytest.raises(IntegrationError, match=r"max_nfev = 20000 .* at t = 2[89]\.[0-9]+ s of 200 s.*"
                                               r"switched [0-9]+ times on \"x_C' = 0\" \(chattering\)") as error:
        simulate(slider_crank, state, LONG, t_start=tight.t[k], formulation=Baumgarte(10, 10), method="DOP853",
                 rtol=1e-9, atol=1e-9, switching="naive", max_nfev=20_000)
    partial = error.value.result
    assert 20_000 <= partial.nfev < 20_100                  # checked between steps: one step may pass it
    assert partial.t[-1] < 30.0                               # 20 000 evaluations bought less than 2 s
    steps = np.diff(partial.t)
    assert steps[-50:].max() < 1e-2 * steps[:10].max()        # the step size collapsed at the switch
    stuck_at = events.sticking_intervals[0][0]
    assert abs(partial.s[0, -1] - events.s[0, -1]) < 1e-3 and partial.t[-1] > stuck_at


def test_naive_switching_without_a_switch_reproduces_the_event_based_run(slider_crank):
    """Where the force never switches, naive and event-based runs solve the same smooth ODE."""
    case = CASES[2]
    state = initial_state(slider_crank, case.phi0, case.dphi0)
    times = np.linspace(0.0, 0.5, 6)
    options = dict(formulation=Baumgarte(10, 10), method="DOP853", rtol=1e-10, atol=1e-10, t_eval=times)
    events = simulate(slider_crank, state, 0.5, **options)
    assert not events.switch_events
    naive = simulate(slider_crank, state, 0.5, switching="naive", **options)
    assert naive.switching == "naive"
    assert np.max(np.abs(naive.s - events.s)) < 1e-9
    # and take the same steps, which the naive run counts as the event-based one does
    assert naive.n_steps == events.n_steps > 10
    assert np.allclose(naive.step_starts, events.step_starts, rtol=1e-9, atol=0.0)
    assert np.allclose(naive.step_sizes, events.step_sizes, rtol=1e-6, atol=0.0)


def test_naive_switching_stops_at_max_steps_and_says_where(slider_crank):
    state = initial_state(slider_crank, CASES[2].phi0, CASES[2].dphi0)
    with pytest.raises(IntegrationError, match=r"^naive switching reached max_steps = 20 at t = 0\.[0-9]+ s of "
                                               r"1 s \(step size [0-9.e-]+ s\); use switching='events'$") as error:
        simulate(slider_crank, state, 1.0, method="RK45", switching="naive", max_steps=20)
    partial = error.value.result
    assert partial.n_steps == 20 and partial.t[-1] == pytest.approx(partial.step_starts[-1] + partial.step_sizes[-1])


def test_switching_and_the_evaluation_cap_are_validated(slider_crank):
    state = initial_state(slider_crank, math.pi, 1.0)
    with pytest.raises(InputError, match=r"^switching: unknown 'if'; choose one of events, naive"):
        simulate(slider_crank, state, 1.0, switching="if")
    with pytest.raises(InputError, match=r"^max_nfev: must be an integer >= 1, got 0$"):
        simulate(slider_crank, state, 1.0, max_nfev=0)
    with pytest.raises(IntegrationError, match=r"used up max_nfev = 50 right-hand-side evaluations at t = "):
        simulate(slider_crank, state, 1.0, max_nfev=50)


def test_the_forcing_period_is_read_off_the_model(slider_crank, conservative_slider_crank, four_bar):
    """The drive's ripple 0.01 sin(Omega t), Omega = 2 pi rad/s, has period 1 s; no drive, no time at all."""
    from closedloop.simulation.switching import forcing_period

    names = [str(p) for p in slider_crank.model.parameters]
    omega = slider_crank.parameter_values[names.index("omega")]
    assert omega == pytest.approx(2 * math.pi)
    assert forcing_period(slider_crank) == pytest.approx(2 * math.pi / omega, rel=1e-12)
    assert forcing_period(conservative_slider_crank) == 0.0
    assert forcing_period(four_bar) == 0.0


@pytest.mark.parametrize("t_end", [1e3, 1e6, 1e9])
def test_a_stuck_slider_is_held_to_any_t_end_in_constant_work(slider_crank, t_end):
    """Case 1 sticks at 37.83 s; past one period of the drive it is never released, so the run ends
    there whatever t_end is: the same output points, the same evaluations, one held interval."""
    case = CASES[1]
    state = initial_state(slider_crank, case.phi0, case.dphi0)
    short = simulate(slider_crank, state, 100.0, formulation=Minimal(), method="DOP853")
    long = simulate(slider_crank, state, t_end, formulation=Minimal(), method="DOP853")
    assert long.sticking_intervals[-1][0] == pytest.approx(37.834, abs=1e-3)
    assert long.sticking_intervals[-1][1] == t_end and long.t[-1] == t_end
    assert long.t.size == short.t.size and long.nfev == short.nfev
    assert np.all(long.sd[:, -1] == 0.0) and np.array_equal(long.s[:, -1], short.s[:, -1])


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
    # the released state leaves on the branch its free motion rises onto: no event at the release
    # time but the release (the other branch stopped at once, with a zero-length "crossed" event)
    assert [e.action for e in result.switch_events if e.t == released[0].t] == ["released"]
    assert result.max_constraint_error < 1e-5



def test_the_rule_decides_one_state_as_it_decides_many():
    """switching.decide for one state (floats, as Run.decide calls it) and for arrays (the basin map)
    give the same sides and sticking, including the boundaries (a rate of 0) and NaN."""
    from closedloop.simulation import switching

    rates = (-2.0, -0.0, 0.0, 3.0, math.nan)
    cases = [(off, on, side) for off in rates for on in rates for side in (False, True)]
    off, on, side = (np.array(column) for column in zip(*cases))
    sides, sticks = switching.decide(off, on, side)
    for k, (a, b, c) in enumerate(cases):
        one = switching.decide(np.float64(a), b, np.bool_(c))
        assert one == (bool(sides[k]), bool(sticks[k])), (a, b, c)
        assert type(one[0]) is bool and type(one[1]) is bool
    assert switching.decide(1.0, -1.0, False) == (False, True)       # both push onto the surface: it sticks
    assert switching.decide(-1.0, -1.0, True) == (False, False)      # both leave to the off side


def test_a_naive_run_with_projected_projects(slider_crank):
    """switching='naive' runs the formulation's own integrator: Projected resets f and f' after every step
    (its residuals at round-off), where the augmented system it projects drifts to the tolerance."""
    from closedloop import Augmented, Projected

    state = initial_state(slider_crank, get_case(2).phi0, get_case(2).dphi0)
    settings = dict(method="RK45", rtol=1e-6, atol=1e-6, switching="naive")
    projected = simulate(slider_crank, state, 3.0, formulation=Projected(), **settings)
    augmented = simulate(slider_crank, state, 3.0, formulation=Augmented(), **settings)
    assert augmented.max_constraint_error > 1e-7
    assert projected.max_constraint_error < 1e-12 and projected.max_velocity_constraint_error < 1e-10


@pytest.mark.parametrize("option", [dict(stop_when=lambda t, s, sd: t - 1.0), dict(work=True)],
                         ids=["stop_when", "work"])
def test_a_naive_run_refuses_what_it_does_not_do(slider_crank, option):
    state = initial_state(slider_crank, get_case(2).phi0, get_case(2).dphi0)
    name = next(iter(option))
    with pytest.raises(InputError, match=rf"^{name}: a run with switching='naive' neither stops early"):
        simulate(slider_crank, state, 3.0, switching="naive", **option)
