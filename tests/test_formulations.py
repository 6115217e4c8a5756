"""The formulations solve the same motion: against each other and against an independent ODE; Baumgarte's
gains, the multipliers, and minimal coordinates' one ODE for one state and a batch.

The closed form (26) and the projection have their own files, test_closed_form.py and test_projection.py.
"""

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from closedloop import (Augmented, Baumgarte, InputError, Minimal, Orthogonal, baumgarte_from_step,
                        consistent_initial_state, simulate)
from closedloop.formulations.minimal import MinimalUnpacker, minimal_accelerations
from closedloop.linalg import orthogonal_complement_many
from closedloop.slider_crank import CASES, initial_state

FORMULATIONS = [Augmented(), Baumgarte(5, 5), Baumgarte(10, 10), Orthogonal(5, 5), Minimal()]


def state_at(result, k=-1):
    return np.concatenate((result.s[:, k], result.sd[:, k]))


@pytest.fixture(scope="module")
def minimal_references(slider_crank):
    """Minimal coordinates at rtol = atol = 1e-12: the accuracy reference, state at t = 10 s."""
    refs = {}
    for number, case in CASES.items():
        state = initial_state(slider_crank, case.phi0, case.dphi0)
        result = simulate(slider_crank, state, 10.0, formulation=Minimal(), method="DOP853",
                          rtol=1e-12, atol=1e-12, t_eval=[10.0])
        refs[number] = state_at(result)
    return refs


@pytest.mark.parametrize("formulation", FORMULATIONS, ids=lambda f: f"{f.name}{getattr(f, 'alpha', '')}")
@pytest.mark.parametrize("number", sorted(CASES))
def test_every_formulation_agrees_with_minimal_coordinates_at_t10(slider_crank, minimal_references,
                                                                   formulation, number):
    case = CASES[number]
    state = initial_state(slider_crank, case.phi0, case.dphi0)
    result = simulate(slider_crank, state, 10.0, formulation=formulation, method="DOP853",
                      rtol=1e-10, atol=1e-10, t_eval=[10.0])
    assert np.max(np.abs(state_at(result) - minimal_references[number])) < 1e-6


@pytest.mark.parametrize("formulation", [Augmented(), Baumgarte(5, 5), Orthogonal(5, 5), Minimal()],
                         ids=lambda f: f.name)
def test_pendulum_in_redundant_coordinates_matches_its_own_ode(pendulum, formulation):
    """A generic model, not the slider-crank: theta'' = -(g/l) sin theta integrated directly."""
    g, l = 9.81, 1.5
    theta0, omega0 = 2.0, 0.5                        # large swing: the nonlinearity matters
    state = consistent_initial_state(pendulum, [theta0], [omega0], [1.0, 0.0])
    times = np.linspace(0.0, 5.0, 11)
    result = simulate(pendulum, state, 5.0, formulation=formulation, method="DOP853",
                      rtol=1e-11, atol=1e-11, t_eval=times)
    exact = solve_ivp(lambda t, y: [y[1], -g / l * math.sin(y[0])], (0, 5), [theta0, omega0],
                      method="DOP853", rtol=1e-13, atol=1e-13, t_eval=times)
    assert np.max(np.abs(result.coordinate("theta") - exact.y[0])) < 1e-7
    assert np.max(np.abs(result.velocity("theta") - exact.y[1])) < 1e-7
    assert np.max(np.abs(result.coordinate("y") + l * np.cos(exact.y[0]))) < 1e-7


def test_baumgarte_damps_a_constraint_error_that_augmented_lets_drift(slider_crank):
    """At a loose tolerance, (17) keeps |f| bounded where (12) lets it grow (13)."""
    case = CASES[2]
    state = initial_state(slider_crank, case.phi0, case.dphi0)
    loose = dict(method="RK45", rtol=1e-5, atol=1e-5)
    drift = simulate(slider_crank, state, 20.0, formulation=Augmented(), **loose)
    held = simulate(slider_crank, state, 20.0, formulation=Baumgarte(10, 10), **loose)
    assert drift.max_constraint_error > 10 * held.max_constraint_error
    late = drift.t > 10
    assert np.max(drift.constraint_error[late]) > np.max(drift.constraint_error[~late])  # it grows


def test_baumgarte_step_rule():
    rule = baumgarte_from_step(0.01)
    assert (rule.alpha, rule.beta) == pytest.approx((100.0, 100.0 * math.sqrt(2)))
    with pytest.raises(InputError, match="step"):
        baumgarte_from_step(0.0)


def test_multipliers_only_when_asked_and_equal_across_formulations(slider_crank):
    case = CASES[4]
    state = initial_state(slider_crank, case.phi0, case.dphi0)
    times = np.linspace(0, 5, 6)
    plain = simulate(slider_crank, state, 5.0, formulation=Baumgarte(), t_eval=times)
    assert plain.multipliers is None
    options = dict(method="DOP853", rtol=1e-11, atol=1e-11, t_eval=times, multipliers=True)
    lam_a = simulate(slider_crank, state, 5.0, formulation=Augmented(), **options).multipliers
    lam_m = simulate(slider_crank, state, 5.0, formulation=Minimal(), **options).multipliers
    assert lam_a.shape == (2, 6)
    assert np.max(np.abs(lam_a - lam_m)) < 1e-5 * np.max(np.abs(lam_a))
    # (31): m3 x'' = Q3 + lambda1, so lambda1 carries the slider's inertia and gas force
    assert np.max(np.abs(lam_a[0])) > 1.0


def test_multiplier_lambda1_is_the_rod_force_on_the_slider_of_equation_31(slider_crank):
    """(31): m3 x'' = Q3 + lambda1, with Q3 = +F_gas (the paper's reading); x'' by finite differences."""
    from closedloop.slider_crank import gas_force

    case = CASES[4]
    state = initial_state(slider_crank, case.phi0, case.dphi0)
    dt = 1e-3
    times = np.arange(0.0, 3.0 + dt / 2, dt)
    result = simulate(slider_crank, state, 3.0, formulation=Baumgarte(5, 5), method="DOP853",
                      rtol=1e-11, atol=1e-11, t_eval=times, multipliers=True)
    x, x_dot = result.coordinate("x"), result.velocity("x")
    x_acc = np.gradient(x_dot, dt)
    switches = np.array([e.t for e in result.switch_events])
    smooth = np.min(np.abs(times[:, None] - switches[None, :]), axis=1) > 3 * dt   # x'' jumps at switches
    smooth[[0, -1]] = False
    lambda1 = 25.0 * x_acc - gas_force(x, x_dot)                # m3 = 25 kg
    assert smooth.sum() > 2500
    assert np.max(np.abs(result.multipliers[0, smooth] - lambda1[smooth])) < 1e-3 * np.max(np.abs(lambda1))


def test_the_minimal_ode_is_one_function_for_one_state_and_a_batch(slider_crank):
    states = [initial_state(slider_crank, angle, speed) for angle, speed in ((0.5, 1.0), (2.5, -0.7))]
    one = [Minimal().accelerations(slider_crank, 0.3, state.s, state.sd) for state in states]
    for state, accelerations in zip(states, one):         # the same s'' as the augmented system (12)
        np.testing.assert_allclose(accelerations, slider_crank.constrained_accelerations(0.3, state.s, state.sd)[0],
                                   rtol=1e-11, atol=1e-12)
    s = np.column_stack([state.s for state in states])
    sd = np.column_stack([state.sd for state in states])
    M, p1, _, Phi, gamma = slider_crank.dynamics_many(0.3, s, sd)
    p1 = p1 + np.column_stack([slider_crank.force(0.3, state.s, state.sd, slider_crank.force.mode_at(
        0.3, state.s, state.sd)) for state in states])
    R = orthogonal_complement_many(Phi, slider_crank.q_index, slider_crank.z_index)
    qdd, c = minimal_accelerations(M, p1, Phi, gamma, R, slider_crank.z_index)
    batch = np.einsum("ilk,lk->ik", R, qdd) + c
    np.testing.assert_allclose(batch, np.column_stack(one), rtol=1e-12, atol=1e-13)


def test_the_minimal_unpacker_is_an_object_with_seed_and_with_R(slider_crank):
    state = initial_state(slider_crank, 1.0, 2.0)
    unpack = Minimal().unpacker(slider_crank)
    assert isinstance(unpack, MinimalUnpacker)
    unpack.seed(state.s)
    y = Minimal().pack(slider_crank, state.s, state.sd)
    s, sd = unpack(y, 0.0)
    np.testing.assert_allclose(s, state.s, atol=1e-14)
    np.testing.assert_allclose(sd, state.sd, atol=1e-14)
    again, R = unpack.with_R(y, 0.0)
    assert again is s                                 # the same y costs nothing: the last solution comes back
    assert R[0, 0] == 1.0 and R[2, 0] == pytest.approx(state.sd[2] / state.sd[0], rel=1e-13)   # x_C' = R_x phi'
    moved, _ = unpack(y + np.array([0.01, 0.0]), 0.01)  # Newton follows q from the prediction
    assert moved[0] == 1.01 and 2.0 * math.sin(1.01) == pytest.approx(3.5 * math.sin(moved[1]), abs=1e-14)


@pytest.mark.parametrize("alpha, beta", [(7.0, 3.0), (0.0, 0.0)])
def test_baumgarte_accelerations_satisfy_the_stabilised_constraint_equation(alpha, beta):
    """(16)-(17) at a state off the constraints (f != 0, f' != 0): Phi s'' + Phi_s' s' = -2 alpha f' - beta^2 f,
    with f' = Phi s', and M s'' + Phi^T lambda = p1; alpha = beta = 0 gives (12), the augmented system."""
    from closedloop.slider_crank import slider_crank_system

    system = slider_crank_system(gas=False)
    state = initial_state(system, 1.0, 2.0)
    s, sd = state.s + [0.0, 1e-3, -2e-3], state.sd + [0.0, 0.01, 0.02]
    sdd = Baumgarte(alpha, beta).accelerations(system, 0.3, s, sd)
    M, p1, f, Phi, gamma = system.dynamics(0.3, s, sd)
    assert np.linalg.norm(f) > 1e-4 and np.linalg.norm(Phi @ sd) > 1e-3
    assert np.allclose(Phi @ sdd + gamma, -2.0 * alpha * (Phi @ sd) - beta**2 * f, rtol=0, atol=1e-10)
    multipliers = np.linalg.lstsq(Phi.T, p1 - M @ sdd, rcond=None)[0]      # M s'' - p1 in the range of Phi^T
    assert np.allclose(M @ sdd + Phi.T @ multipliers, p1, rtol=0, atol=1e-9)
    if alpha == beta == 0.0:
        assert np.allclose(sdd, Augmented().accelerations(system, 0.3, s, sd), rtol=0, atol=1e-12)
