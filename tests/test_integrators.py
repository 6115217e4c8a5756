"""The integrators: RK4's stability theory against the integration, stiff Baumgarte gains and step counts,
output times, minimal coordinates kept on their branch, and clear errors when a run cannot go on.

The compiled DOP853 ("ode.dop853") has its own file, test_ode_dop853.py.
"""

import re
import math

import numpy as np
import pytest

from closedloop import (Augmented, Baumgarte, ClosedForm, IntegrationError, InputError, Minimal, Orthogonal,
                        Projected, SingularConfigurationError, simulate)
from closedloop.fixed_step import (baumgarte_roots, rk4, rk4_baumgarte_growth, rk4_baumgarte_stable,
                                   rk4_real_axis_limit, rk4_stability_function, rk4_stability_map)
from closedloop.slider_crank import CASES, SliderCrankParameters, initial_state, slider_crank_system


@pytest.fixture(scope="module")
def smooth_slider_crank():
    """Table 1 with the drive torque but without the switching gas force."""
    return slider_crank_system(gas=False)


def test_rk4_stability_function_is_the_taylor_polynomial_of_exp():
    z = np.array([0.1, -0.3 + 0.2j, 0.05j])
    assert np.allclose(rk4_stability_function(z), 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24)
    # one RK4 step of y' = mu y from y = 1 is R(mu h): |R - exp| = O(h^5)
    assert abs(rk4_stability_function(-0.01) - math.exp(-0.01)) < 1e-12


def test_rk4_real_axis_limit_is_the_known_2_785():
    assert rk4_real_axis_limit() == pytest.approx(2.785293563, abs=1e-8)
    # beta = 0: the fast root of (15) is -2 alpha, so alpha dt is limited to half of it
    limit = rk4_real_axis_limit() / 2
    assert rk4_baumgarte_stable(limit - 1e-3, 0.0) and not rk4_baumgarte_stable(limit + 1e-3, 0.0)


def test_rk4_imaginary_axis_limit_is_2_sqrt_2():
    """alpha = 0: mu dt = +/- i beta dt, inside RK4's region up to 2 sqrt(2) (an undamped error survives)."""
    assert rk4_baumgarte_stable(0.0, 2 * math.sqrt(2) - 1e-6)
    assert not rk4_baumgarte_stable(0.0, 2 * math.sqrt(2) + 1e-3)
    # |R(iy)|^2 = 1 - y^6/72 + y^8/576, which is <= 1 exactly for y^2 <= 8
    assert rk4_baumgarte_growth(0.0, 1.0) == pytest.approx(math.sqrt(1 - 1 / 72 + 1 / 576), abs=1e-12)


def test_baumgarte_roots_solve_the_characteristic_equation():
    alpha, beta = np.array([1.0, 5.0, 3.0]), np.array([2.0, 5.0, 1.0])
    for mu in baumgarte_roots(alpha, beta):
        assert np.allclose(mu**2 + 2 * alpha * mu + beta**2, 0)


def test_rk4_is_fourth_order_on_the_mechanism(smooth_slider_crank):
    system = smooth_slider_crank
    state = initial_state(system, CASES[2].phi0, CASES[2].dphi0)
    reference = simulate(system, state, 0.5, formulation=Minimal(), method="DOP853", rtol=1e-13, atol=1e-13,
                         t_eval=[0.5])
    errors = []
    for step in (0.05, 0.025):
        run = rk4(system, Minimal(), state.s, state.sd, step, round(0.5 / step))
        assert run.t[-1] == pytest.approx(0.5)
        errors.append(abs(run.s[0, -1] - reference.s[0, -1]))
    assert 12 < errors[0] / errors[1] < 20          # 2^4 = 16


def test_observed_rk4_map_agrees_with_linear_theory(smooth_slider_crank):
    system = smooth_slider_crank
    state = initial_state(system, CASES[2].phi0, CASES[2].dphi0)
    s0, sd0 = state.s + [0.0, 1e-4, 0.0], state.sd + [0.0, 1e-3, 0.0]
    alpha_steps, beta_steps = np.linspace(0.1, 2.0, 8), np.linspace(0.1, 4.0, 8)
    growth = rk4_stability_map(system, s0, sd0, 1e-3, alpha_steps, beta_steps, n_steps=40)
    theory = rk4_baumgarte_stable(alpha_steps[None, :], beta_steps[:, None])
    observed = growth <= 1.0
    assert 0.2 < theory.mean() < 0.8                  # the grid straddles the boundary
    assert (observed == theory).mean() >= 0.9


def test_rk4_map_at_once_is_rk4_cell_by_cell(smooth_slider_crank):
    """The map integrates its cells as one batch; each cell is the rk4 run of its own Baumgarte gains,
    including the cells that diverge and stop early (their growth at the stop, above 1e3)."""
    system = smooth_slider_crank
    state = initial_state(system, CASES[2].phi0, CASES[2].dphi0)
    s0, sd0 = state.s + [0.0, 1e-4, 0.0], state.sd + [0.0, 1e-3, 0.0]
    alpha_steps, beta_steps = np.linspace(0.1, 2.5, 5), np.linspace(0.1, 4.5, 4)
    growth = rk4_stability_map(system, s0, sd0, 1e-3, alpha_steps, beta_steps, n_steps=60)
    one_by_one = np.array([[rk4(system, Baumgarte(a / 1e-3, b / 1e-3), s0, sd0, 1e-3, 60, divergence=1e3).growth
                            for a in alpha_steps] for b in beta_steps])
    assert growth.shape == (4, 5)
    assert growth.max() > 1e3 and growth.min() < 1.0                  # decaying and stopped cells both
    np.testing.assert_allclose(growth, one_by_one, rtol=1e-7)


def test_rk4_takes_every_formulation_and_closed_form_is_baumgarte(smooth_slider_crank):
    """ClosedForm's generated right-hand side returns a list (for ode.dop853): rk4 took it for an array
    and raised TypeError. ClosedForm(5, 5) is (15) solved in closed form: the same steps as Baumgarte(5, 5)."""
    state = initial_state(smooth_slider_crank, 1.0, 1.0)
    closed = rk4(smooth_slider_crank, ClosedForm(5, 5), state.s, state.sd, 0.01, 100)
    baumgarte = rk4(smooth_slider_crank, Baumgarte(5, 5), state.s, state.sd, 0.01, 100)
    assert closed.diverged_at is None and closed.t[-1] == pytest.approx(1.0)
    assert np.max(np.abs(closed.s - baumgarte.s)) < 1e-10
    assert abs(closed.s[0, -1] - closed.s[0, 0]) > 0.1                  # the crank turned


def test_rk4_refuses_projected_which_it_would_run_unprojected(smooth_slider_crank):
    """Projected's projection lives in solve_ivp's steps; rk4 ran it as the plain augmented system
    (the same states to the last bit) without a word."""
    state = initial_state(smooth_slider_crank, 1.0, 1.0)
    with pytest.raises(InputError, match=r"^formulation: Projected cannot run"):
        rk4(smooth_slider_crank, Projected(), state.s, state.sd, 1e-3, 10)
    rk4(smooth_slider_crank, Augmented(), state.s, state.sd, 1e-3, 10)        # its unprojected twin runs


def test_the_rk4_map_refuses_a_start_on_the_constraints(smooth_slider_crank):
    """From a consistent start |f(0)| is round-off (about 1e-15 m), and the growth of |f| over it
    called stable cells unstable (growths of 1e6 to 1e9); the map now refuses such a start."""
    state = initial_state(smooth_slider_crank, 1.0, 1.0)
    with pytest.raises(InputError, match=r"^s0: must lie off the constraints by \|f\(s0\)\| >= 1e-09 m"):
        rk4_stability_map(smooth_slider_crank, state.s, state.sd, 1e-3, [0.1], [0.1], n_steps=5)
    growth = rk4_stability_map(smooth_slider_crank, state.s + [0, 1e-4, 0], state.sd, 1e-3, [0.1], [0.1],
                               n_steps=5)
    assert 0.0 < growth[0, 0] < 1.0                                   # alpha dt = beta dt = 0.1: it decays


def test_rk4_refuses_switched_forces_and_bad_steps(smooth_slider_crank):
    state = initial_state(smooth_slider_crank, 1.0, 1.0)
    with pytest.raises(InputError, match="switches"):
        rk4(slider_crank_system(), Baumgarte(), state.s, state.sd, 1e-3, 10)
    with pytest.raises(InputError, match="step"):
        rk4(smooth_slider_crank, Baumgarte(), state.s, state.sd, -1e-3, 10)


def test_step_counts_collapse_for_explicit_methods_not_for_implicit(slider_crank):
    state = initial_state(slider_crank, CASES[2].phi0, CASES[2].dphi0)
    steps = {}
    for method in ("RK45", "Radau"):
        for gain in (10.0, 1e4):
            result = simulate(slider_crank, state, 0.2, formulation=Baumgarte(gain, gain), method=method,
                              rtol=1e-8, atol=1e-8)
            assert np.sum(result.step_sizes) == pytest.approx(0.2)
            steps[method, gain] = result.n_steps
    assert steps["RK45", 1e4] > 20 * steps["RK45", 10.0]
    assert steps["RK45", 1e4] > 10 * steps["Radau", 1e4]
    # explicit: the step is bounded by stability, h alpha of order one (DOPRI5's real-axis limit is 3.3)
    assert 0.2 / steps["RK45", 1e4] * 1e4 < 3.4


def test_n_steps_are_the_solver_steps(conservative_slider_crank):
    state = initial_state(conservative_slider_crank, 1.0, 1.0)
    result = simulate(conservative_slider_crank, state, 2.0, method="RK45")
    assert result.t.size == result.n_steps + 1
    assert np.allclose(np.diff(result.t), result.step_sizes)


@pytest.mark.parametrize("method, formulation", [("RK45", Baumgarte()), ("ode.dop853", ClosedForm())])
def test_step_starts_are_where_each_step_began_across_switches(slider_crank, method, formulation):
    # 50 rad/s over 0.5 s: the gas force switches 15 times, and each switch restarts the run
    result = simulate(slider_crank, initial_state(slider_crank, math.pi, 50.0), 0.5, formulation=formulation,
                      method=method, rtol=1e-8, atol=1e-8)
    starts, sizes = result.step_starts, result.step_sizes
    switches = np.array([event.t for event in result.switch_events])
    assert starts.size == sizes.size == result.n_steps and switches.size >= 10
    assert starts[0] == 0.0 and np.all(np.diff(starts) > 0)
    ends = starts + sizes
    assert ends[-1] == pytest.approx(0.5, abs=1e-12)
    # a step begins where the one before ended, except after a switch: the step that crossed it ends
    # beyond it (it counts whole), and the next begins at the switch
    restarts = ~np.isclose(starts[1:], ends[:-1], rtol=0.0, atol=1e-12)
    assert np.array_equal(starts[1:][restarts], switches)
    assert np.all(ends[:-1][restarts] > switches)
    # so the running sum of the steps is not the time: it runs past every switch
    assert np.sum(sizes) - 0.5 == pytest.approx(np.sum(ends[:-1][restarts] - switches), rel=1e-9)


@pytest.mark.parametrize("method, formulation", [("RK45", Baumgarte()), ("DOP853", Baumgarte()),
                                                 ("ode.dop853", ClosedForm())])
def test_max_steps_bounds_the_accepted_steps_exactly(slider_crank, method, formulation):
    # 50 rad/s over 0.5 s, 15 switches: a run that needs n steps passes with max_steps = n, not with n - 1
    # (ode.dop853's compiled code counts rejected steps too and lets one more through: the bound is ours)
    start, options = initial_state(slider_crank, math.pi, 50.0), dict(formulation=formulation, method=method)
    needed = simulate(slider_crank, start, 0.5, **options).n_steps
    assert simulate(slider_crank, start, 0.5, max_steps=needed, **options).n_steps == needed
    with pytest.raises(IntegrationError, match=rf"max_steps = {needed - 1} at t = "):
        simulate(slider_crank, start, 0.5, max_steps=needed - 1, **options)


def test_max_steps_error_names_time_step_and_advice(slider_crank):
    state = initial_state(slider_crank, CASES[2].phi0, CASES[2].dphi0)
    with pytest.raises(IntegrationError) as error:
        simulate(slider_crank, state, 1.0, formulation=Baumgarte(1e5, 1e5), method="RK45", max_steps=300)
    message = str(error.value)
    assert "max_steps = 300" in message and "at t = " in message and "last step size " in message
    assert "implicit method" in message and "alpha = 100000" in message
    t_reached = float(message.split("at t = ")[1].split(" s")[0])
    assert 0 < t_reached < 0.1                         # 300 steps of a few microseconds
    with pytest.raises(InputError, match="max_steps"):
        simulate(slider_crank, state, 1.0, max_steps=0)


def test_step_size_underflow_error_names_time_and_step():
    """A force that blows up like |1 - t|^-1.5: the steps shrink to round-off at t = 1 s."""
    from closedloop import System, consistent_initial_state
    from tests.conftest import pendulum_model

    def force(t, s, sd):
        return np.array([abs(1.0 - t) ** -1.5, 0.0, 0.0])

    system = System(pendulum_model(), {"m": 2.0, "l": 1.5, "g": 9.81}, force=force)
    state = consistent_initial_state(system, [0.3], [0.0], [0.4, -1.4])
    with pytest.raises(IntegrationError) as error:
        simulate(system, state, 2.0, formulation=Baumgarte(), method="RK45")
    message = str(error.value)
    assert "step size underflowed" in message and "at t = 1 s" in message and re.search(r"the last accepted step was [0-9.]+e-1[4-6] s", message)
    assert "implicit method" in message


def test_heavy_slider_on_a_light_crank_makes_minimal_jump_branch_clearly():
    """m3 = 1e6 kg on 1e-6 kg links: the crank whips through the dead centres, Newton's z jumps."""
    parameters = SliderCrankParameters(m1=1e-6, I1=2.25e-6, m2=1e-6, I2=1e-6, m3=1e6)
    system = slider_crank_system(parameters)
    state = initial_state(system, CASES[2].phi0, CASES[2].dphi0)
    with pytest.raises(SingularConfigurationError, match=r"at t = 0\.68[0-9]* s: det\(Phi_z\) changed sign.*NullSpace") as error:
        simulate(system, state, 2.0, formulation=Minimal(), method="DOP853")
    # the cause named is the step, not a dead position: Table 1's Phi_z has none (l2 > l1)
    assert "too fast for the step" in str(error.value) and "dead position" not in str(error.value)


@pytest.mark.parametrize("method", ["RK45", "LSODA"])
def test_heavy_slider_whip_is_followed_through_picosecond_steps(method):
    """The same mechanism with no torque and no gas force, so that T + V is conserved: the crank whips through
    each dead centre at about 1e6 rad/s, in windows of 100 steps that advance less than 1e-5 of the run (the
    crawl check's trigger). Nothing in the state makes those steps singular (Phi_s and the forces are regular
    there), so they are the motion's own and the run goes on through them, conserving the energy."""
    parameters = SliderCrankParameters(m1=1e-6, I1=2.25e-6, m2=1e-6, I2=1e-6, m3=1e6)
    system = slider_crank_system(parameters, torque=False, gas=False)
    state = initial_state(system, CASES[2].phi0, CASES[2].dphi0)
    result = simulate(system, state, 2.0, formulation=Baumgarte(), method=method)
    assert result.t[-1] == 2.0
    assert np.convolve(result.step_sizes, np.ones(100), "valid").min() < 1e-5 * 2.0
    assert np.max(np.abs(result.velocity("phi"))) > 1e6
    energy = system.energy(result.s, result.sd)
    assert np.ptp(energy) < 1e-5 * np.max(np.abs(energy))


def test_overflow_in_the_right_hand_side_is_a_clear_error(pendulum):
    from closedloop import System, consistent_initial_state
    from tests.conftest import pendulum_model

    def force(t, s, sd):
        if t > 0.5:
            raise OverflowError("math range error")
        return np.zeros(3)

    system = System(pendulum_model(), {"m": 2.0, "l": 1.5, "g": 9.81}, force=force)
    state = consistent_initial_state(system, [0.3], [0.0], [0.4, -1.4])
    with pytest.raises(IntegrationError) as error:
        simulate(system, state, 1.0, method="RK45")
    message = str(error.value)
    assert "overflowed" in message and "at t = 0.5" in message


def test_tiny_masses_every_formulation_sticks_at_the_same_angle():
    """All bodies at 1e-6 kg: the gas force throws the crank onto its switch x_C' = 0 within a few steps.

    Minimal once stopped here: a long step carried Newton's prediction of z to the other assembly
    branch, although cond(Phi_z) stayed small. Its continuation now follows q in small pieces.
    """
    parameters = SliderCrankParameters(m1=1e-6, I1=2.25e-6, m2=1e-6, I2=1e-6, m3=1e-6)
    system = slider_crank_system(parameters)
    state = initial_state(system, CASES[2].phi0, CASES[2].dphi0)
    finals = []
    for formulation in (Minimal(), Orthogonal(5, 5), Baumgarte()):
        result = simulate(system, state, 2.0, formulation=formulation, method="RK45", rtol=1e-8, atol=1e-8)
        assert result.switch_events[-1].action == "stuck"
        assert result.velocity("phi")[-1] == 0.0
        finals.append(result.coordinate("phi")[-1])
    assert np.ptp(finals) < 1e-6


def test_fast_crank_minimal_stays_on_its_branch():
    """phi'0 = 200 rad/s: a DOP853 step turns the crank by radians, far enough for Newton's first
    guess of z to land on the other branch; the continuation keeps Minimal on its own."""
    system = slider_crank_system()
    state = initial_state(system, math.pi, 200.0)
    runs = [simulate(system, state, 0.3, formulation=formulation, method="DOP853", rtol=1e-11, atol=1e-11)
            for formulation in (Minimal(), Baumgarte())]
    assert abs(runs[0].coordinate("phi")[-1] - runs[1].coordinate("phi")[-1]) < 1e-6
    assert runs[0].max_constraint_error < 1e-10


def test_step_size_scales_inversely_with_crank_speed(slider_crank):
    medians = []
    for speed in (50.0, 200.0):
        state = initial_state(slider_crank, math.pi, speed)
        result = simulate(slider_crank, state, 0.2, formulation=Baumgarte(), method="RK45", rtol=1e-8, atol=1e-8)
        medians.append(np.median(result.step_sizes))
    assert 2.5 < medians[0] / medians[1] < 6            # 200 / 50 = 4


def test_output_times_may_end_before_t_end(slider_crank):
    case = CASES[2]
    result = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 20.0, t_eval=[0.0, 0.5])
    full = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 0.5, t_eval=[0.5])
    assert list(result.t) == [0.0, 0.5]
    assert np.allclose(result.s[:, 1], full.s[:, 0], atol=1e-7)

