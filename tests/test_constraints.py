"""Constraint kinematics: the orthogonality theorem (18)-(20), Phi_s' s', consistent initial values."""

import math

import numpy as np
import pytest
import sympy as sp

from closedloop import (ConvergenceError, MultibodyModel, SingularConfigurationError, System,
                        consistent_initial_state)
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
