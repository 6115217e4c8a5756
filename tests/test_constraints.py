"""Constraint kinematics and the evaluated model: the orthogonality theorem (18)-(20), Phi_s' s', consistent
initial values, Newton on f = 0, and the dynamics (M, p1, f, Phi_s, gamma) for one state and for many."""

import math

import numpy as np
import pytest
import sympy as sp

from closedloop import (ConvergenceError, MultibodyModel, SingularConfigurationError, System,
                        consistent_initial_state)
from closedloop.kinematics import solve_dependent, solve_dependent_many
from closedloop.linalg import orthogonal_complement_many
from closedloop.slider_crank import CASES, initial_state

from .conftest import random_states


def test_orthogonality_phi_s_R_vanishes_at_random_configurations(slider_crank):
    for s, _ in random_states(200, seed=1):
        Phi = slider_crank.jacobian(s)
        R = slider_crank.orthogonal_complement(s)
        assert np.max(np.abs(Phi @ R)) <= 1e-14 * max(1.0, np.max(np.abs(R)))


def test_jacobian_rate_product_matches_finite_difference_of_phi_s_sdot(slider_crank):
    """d/dt [Phi_s(s) s'] along s(t) = s + t s' (s' held fixed) is Phi_s' s'."""
    h = 1e-5
    for s, sd in random_states(50, seed=2):
        gamma = slider_crank.dynamics(0.0, s, sd)[4]

        def phi_sd(tau):
            return slider_crank.jacobian(s + tau * sd) @ sd

        finite_difference = (phi_sd(h) - phi_sd(-h)) / (2 * h)
        assert np.allclose(finite_difference, gamma, rtol=1e-8, atol=1e-8 * np.linalg.norm(sd) ** 2)


@pytest.mark.parametrize("number", sorted(CASES))
def test_consistent_initial_conditions_satisfy_f_and_fdot(slider_crank, number):
    case = CASES[number]
    state = initial_state(slider_crank, case.phi0, case.dphi0)
    f, Phi = slider_crank.constraints_and_jacobian(state.s)
    assert np.linalg.norm(f) < 1e-12
    assert np.linalg.norm(Phi @ state.sd) < 1e-12
    assert math.pi / 2 < state.s[1] < 3 * math.pi / 2          # slider to the right of the crank


def test_inner_dead_centre_at_phi_pi(slider_crank):
    """At phi0 = pi the slider sits at x_C = l2 - l1 = 1.5 m, psi = pi, at rest."""
    state = initial_state(slider_crank, math.pi, 1.0)
    assert state.s[1] == pytest.approx(math.pi, abs=1e-12)
    assert state.s[2] == pytest.approx(1.5, abs=1e-12)
    assert state.sd[2] == pytest.approx(0.0, abs=1e-12)
    assert state.sd[1] == pytest.approx(-2.0 / -3.5, abs=1e-12)  # psi' = l1 cos(phi) / (l2 cos(psi)) phi'


def test_newton_from_a_rough_guess_finds_the_branch_the_guess_selects(slider_crank):
    right = consistent_initial_state(slider_crank, [1.0], [0.3], [2.5, 4.0])
    left = consistent_initial_state(slider_crank, [1.0], [0.3], [0.6, -2.0])
    for state in (right, left):
        assert np.linalg.norm(slider_crank.constraints(state.s)) < 1e-12
    assert right.s[2] > 0 > left.s[2]                           # the two assembly branches


def test_newton_reports_a_mechanism_that_cannot_assemble():
    """l1 > l2 at phi = pi/2: |l1 sin phi| > l2, so (28) has no solution (generic API: no validation)."""
    from closedloop.slider_crank import slider_crank_model

    values = dict(l1=4.0, a1=0.0, m1=1.0, I1=1.0, l2=3.0, a2=1.0, m2=1.0, I2=1.0, m3=1.0, g=9.81,
                  torque_mean=0.0, torque_ripple=0.0, omega=1.0)
    system = System(slider_crank_model(), values)
    with pytest.raises(ConvergenceError, match=r"did not converge.*\|f\| = "):
        consistent_initial_state(system, [math.pi / 2], [0.0], [2.0, 1.0])


def test_singular_phi_z_is_a_clear_error():
    """A point on the unit circle, q = x, z = y: Phi_z = 2y is singular at y = 0."""
    x, y, dx, dy = sp.symbols("x y dx dy")
    circle = MultibodyModel(coordinates=(x, y), velocities=(dx, dy), kinetic_energy=(dx**2 + dy**2) / 2,
                            potential_energy=sp.Integer(0), constraints=(x**2 + y**2 - 1,), independent=(x,))
    with pytest.raises(SingularConfigurationError, match="Phi_z is singular"):
        consistent_initial_state(System(circle), [1.0], [0.0], [0.0])


def test_the_dynamics_are_a_named_tuple_that_still_unpacks(slider_crank):
    state = initial_state(slider_crank, math.pi / 2, 1.0)
    dynamics = slider_crank.dynamics(0.0, state.s, state.sd)
    M, p1, constraint_values, Phi, gamma = dynamics
    assert dynamics.mass_matrix is M and dynamics.jacobian is Phi
    assert dynamics.constraints is constraint_values and dynamics.jacobian_rate_product is gamma
    assert np.abs(dynamics.constraints).max() < 1e-14            # a consistent state: f = 0 (6)
    # Table 1: the slider's mass m3 = 25 kg is the last diagonal entry of M
    assert dynamics.mass_matrix[2, 2] == 25.0
    many = slider_crank.dynamics_many(0.0, state.s[:, None], state.sd[:, None])
    np.testing.assert_allclose(many.jacobian[:, :, 0], Phi, rtol=1e-14)


def test_one_newton_loop_serves_one_state_and_a_batch(slider_crank):
    angles = np.array([0.3, math.pi / 2, 2.0, math.pi, 4.0])
    guesses = np.array([[math.pi - 0.1] * angles.size, [1.0] * angles.size])   # psi near pi, x_C anywhere
    batch, Phi = solve_dependent_many(slider_crank, angles, guesses)
    for j, angle in enumerate(angles):
        one = solve_dependent(slider_crank, np.array([angle]), guesses[:, j])
        np.testing.assert_allclose(batch[:, j], one, rtol=0, atol=1e-14)
        # (27)-(28) with Table 1: l1 sin(phi) = l2 sin(psi) and x_C = l1 cos(phi) - l2 cos(psi)
        assert 2.0 * math.sin(angle) == pytest.approx(3.5 * math.sin(one[1]), abs=1e-14)
        assert one[2] == pytest.approx(2.0 * math.cos(angle) - 3.5 * math.cos(one[1]), abs=1e-14)
    assert batch[2, 3] == pytest.approx(1.5, abs=1e-14)          # phi = pi: x_C = l2 - l1
    np.testing.assert_allclose(Phi[:, :, 1], slider_crank.jacobian(batch[:, 1]), rtol=1e-14, atol=1e-15)


def test_a_batch_that_does_not_assemble_is_refused(slider_crank):
    with pytest.raises(ConvergenceError, match=r"did not converge in 3 iterations for some cells"):
        solve_dependent_many(slider_crank, np.array([1.0, 2.0]), np.array([[3.0, 3.0], [40.0, 1.0]]),
                             max_iterations=3)


def test_the_batched_orthogonal_complement_is_R_of_20_at_every_state(slider_crank):
    angles = np.array([0.4, 1.9, 3.0])
    s, Phi = solve_dependent_many(slider_crank, angles, np.array([[3.0] * 3, [1.5] * 3]))
    R = orthogonal_complement_many(Phi, slider_crank.q_index, slider_crank.z_index)
    assert R.shape == (3, 1, 3)
    for j in range(angles.size):
        np.testing.assert_allclose(R[:, :, j], slider_crank.orthogonal_complement(s[:, j]), rtol=1e-15, atol=0)
        np.testing.assert_allclose(Phi[:, :, j] @ R[:, :, j], 0.0, atol=1e-15)          # (18)
    # dpsi/dphi = l1 cos(phi) / (l2 cos(psi)) from (28)
    assert R[1, 0, 0] == pytest.approx(2.0 * math.cos(0.4) / (3.5 * math.cos(s[1, 0])), rel=1e-14)


def test_arrays_of_states_give_the_same_dynamics_as_one_state(slider_crank):
    """System.dynamics_many and GasForce.many (numpy, many cells) against the one-state functions."""
    rng = np.random.default_rng(3)
    size = 7
    s = np.array([rng.uniform(0, 2 * math.pi, size), rng.uniform(2.5, 3.8, size), rng.uniform(1.5, 5.5, size)])
    sd = rng.normal(size=(3, size))
    t = rng.uniform(0, 20, size)
    mode = rng.random((2, size)) < 0.5
    M, p1, f, Phi, gamma = slider_crank.dynamics_many(t, s, sd)
    force = slider_crank.force.many(t, s, sd, mode)
    for j in range(size):
        one = slider_crank.dynamics(t[j], s[:, j], sd[:, j], tuple(mode[:, j]))
        np.testing.assert_allclose(M[:, :, j], one[0], rtol=1e-13)
        np.testing.assert_allclose(p1[:, j] + force[:, j], one[1], rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(f[:, j], one[2], rtol=1e-13, atol=1e-14)
        np.testing.assert_allclose(Phi[:, :, j], one[3], rtol=1e-13, atol=1e-14)
        np.testing.assert_allclose(gamma[:, j], one[4], rtol=1e-12, atol=1e-12)
