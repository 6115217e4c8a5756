"""The closed form of (26) gives the accelerations of the augmented system (12)/(16).

The reference is the library's numeric solve of the augmented matrix (an
independent route: assembled M, Phi_s, p1 and one linear solve), at random
states of two mechanisms, on every branch of the gas force.
"""

import math

import numpy as np
import pytest

from closedloop import Augmented, Baumgarte, SingularConfigurationError, simulate
from closedloop.formulations import ClosedForm, baumgarte_p2
from closedloop.model import solve_augmented
from closedloop.slider_crank import initial_state

from .conftest import random_states

GAINS = [(0.0, 0.0), (5.0, 5.0), (2.0, 7.5)]


def augmented_accelerations(system, t, s, sd, mode, alpha, beta):
    M, p1, f, Phi, gamma = system.dynamics(t, s, sd, mode)
    return solve_augmented(M, Phi, p1, baumgarte_p2(Phi, gamma, f, sd, alpha, beta))[0]


@pytest.mark.parametrize("alpha, beta", GAINS)
@pytest.mark.parametrize("mode", [(False, False), (True, False), (True, True)])
def test_closed_form_equals_the_augmented_solve_on_the_slider_crank(slider_crank, alpha, beta, mode):
    formulation = ClosedForm(alpha, beta)
    for s, sd in random_states(25, seed=11):
        t = float(np.random.default_rng(int(s[0] * 1e6)).uniform(0, 20))
        expected = augmented_accelerations(slider_crank, t, s, sd, mode, alpha, beta)
        got = formulation.accelerations(slider_crank, t, s, sd, mode)
        assert np.allclose(got, expected, rtol=1e-10, atol=1e-10 * np.max(np.abs(expected)))


@pytest.mark.parametrize("alpha, beta", GAINS)
def test_closed_form_equals_the_augmented_solve_on_the_four_bar(four_bar, alpha, beta):
    rng = np.random.default_rng(5)
    for _ in range(25):
        s = np.array([rng.uniform(0, 2 * math.pi), rng.uniform(0, 2 * math.pi), rng.uniform(0, 2 * math.pi)])
        sd = rng.normal(size=3)
        expected = augmented_accelerations(four_bar, 0.0, s, sd, (), alpha, beta)
        got = ClosedForm(alpha, beta).accelerations(four_bar, 0.0, s, sd)
        assert np.allclose(got, expected, rtol=1e-9, atol=1e-9 * np.max(np.abs(expected)))


def test_a_folded_four_bar_is_a_clear_singular_configuration_error(four_bar):
    # coupler and rocker parallel (theta2 = theta3 = 0): det Phi_z = l2 l3 sin(theta2 - theta3) = 0 exactly
    rhs = ClosedForm().make_rhs(four_bar, (), None)
    with pytest.raises(SingularConfigurationError, match=r"t = 1\.5 s.*det Phi_z = 0"):
        rhs(1.5, np.array([0.3, 0.0, 0.0, 1.0, 0.0, 0.0]))


def test_closed_form_simulation_matches_baumgarte_step_for_step(slider_crank):
    state = initial_state(slider_crank, math.pi / 2, 1.0)
    a = simulate(slider_crank, state, 5.0, formulation=ClosedForm(5, 5), method="DOP853", rtol=1e-10, atol=1e-10,
                 t_eval=np.linspace(0, 5, 11))
    b = simulate(slider_crank, state, 5.0, formulation=Baumgarte(5, 5), method="DOP853", rtol=1e-10, atol=1e-10,
                 t_eval=np.linspace(0, 5, 11))
    assert np.max(np.abs(a.s - b.s)) < 1e-9
    assert abs(a.nfev - b.nfev) <= 0.02 * b.nfev          # the same ODE: the same steps, up to round-off
    c = simulate(slider_crank, state, 5.0, formulation=ClosedForm(0, 0), method="DOP853", rtol=1e-10,
                 atol=1e-10, t_eval=np.linspace(0, 5, 11))
    d = simulate(slider_crank, state, 5.0, formulation=Augmented(), method="DOP853", rtol=1e-10, atol=1e-10,
                 t_eval=np.linspace(0, 5, 11))
    assert np.max(np.abs(c.s - d.s)) < 1e-9


@pytest.mark.parametrize("alpha, beta", GAINS)
@pytest.mark.parametrize("mode", [(False, False), (False, True), (True, False), (True, True)])
def test_the_folded_right_hand_side_equals_the_closed_form_plus_the_force_call(slider_crank, alpha, beta, mode):
    """closed_form_rhs folds the gas force (sympy, per branch) and the gains into one function; the
    reference is the generic closed form with the force evaluated by GasForce.components."""
    from closedloop.formulations.closed_form import closed_form_accelerations, closed_form_rhs

    folded = closed_form_rhs(slider_crank, mode, alpha, beta)
    unfolded = closed_form_accelerations(slider_crank)
    outside = 0
    for s, sd in random_states(40, seed=5):          # x_C in (1, 6): inside and outside the stroke 1.5-5.5
        t = float(np.random.default_rng(int(sd[0] * 1e6) % 2**32).uniform(0, 20))
        s_list, sd_list = s.tolist(), sd.tolist()
        force = slider_crank.force.components(t, s_list, sd_list, mode)
        outside += force[2] == 0.0
        expected = np.array(sd_list + unfolded(t, s_list, sd_list, force, alpha, beta))
        got = np.array(folded(t, np.concatenate((s, sd))))
        assert np.allclose(got, expected, rtol=1e-12, atol=1e-12 * np.max(np.abs(expected)))
    assert 0 < outside < 40 or not mode[0]


def test_folded_functions_are_shared_by_branches_with_the_same_force_and_missing_forms_fall_back(slider_crank):
    from closedloop.formulations.closed_form import closed_form_rhs
    from closedloop.forces import SwitchedForce
    from closedloop.model import System

    # the gas force is 0 on both branches "moving inward": one function for the two
    assert closed_form_rhs(slider_crank, (False, True), 1, 1) is closed_form_rhs(slider_crank, (False, False), 1, 1)
    assert closed_form_rhs(slider_crank, (True, True), 1, 1) is not closed_form_rhs(slider_crank, (True, False), 1, 1)

    class Spring(SwitchedForce):                     # a force with no sympy form: the generic path
        def __call__(self, t, s, sd, mode):
            return np.array([0.0, 0.0, -30.0 * (s[2] - 3.0)])

    plain = System(slider_crank.model, dict(zip(map(str, slider_crank.model.parameters),
                                                slider_crank.parameter_values)), Spring())
    assert closed_form_rhs(plain, (), 1, 1) is None
    s, sd = next(random_states(1, seed=3))
    got = ClosedForm(1, 1).accelerations(plain, 0.5, s, sd, ())
    expected = augmented_accelerations(plain, 0.5, s, sd, (), 1.0, 1.0)
    assert np.allclose(got, expected, rtol=1e-10)


@pytest.mark.parametrize("which", ["slider_crank", "four_bar"])
def test_the_partition_determinant_is_det_phi_z(which, request):
    """linalg.partition_determinant, the one det Phi_z of the formulations and the branch guard, one state and many."""
    from closedloop.linalg import partition_determinant

    system = request.getfixturevalue(which)
    rng = np.random.default_rng(8)
    s = rng.uniform(-3.0, 3.0, size=(system.n, 30))
    jacobians = np.stack([system.jacobian(s[:, k]) for k in range(30)], axis=2)
    expected = [np.linalg.det(jacobians[:, system.z_index, k]) for k in range(30)]
    assert np.allclose(partition_determinant(jacobians, system.z_index), expected, rtol=1e-12, atol=1e-12)
    assert partition_determinant(jacobians[:, :, 4], system.z_index) == pytest.approx(expected[4], rel=1e-12)
    three = rng.normal(size=(3, 5, 7))                   # r = 3: LU, the same numbers
    assert np.allclose(partition_determinant(three, [0, 2, 4]),
                       [np.linalg.det(three[:, [0, 2, 4], k]) for k in range(7)], rtol=1e-12)
