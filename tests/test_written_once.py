"""Rules written once: the method names, the input checks, the gas law, Newton on f = 0, the minimal ODE."""

import math

import numpy as np
import pytest

import closedloop.methods as methods
import closedloop.validation as validation
from closedloop import Baumgarte, ConvergenceError, InputError, Minimal, System, baumgarte_from_step
from closedloop.formulations.minimal import MinimalUnpacker, minimal_accelerations
from closedloop.linalg import orthogonal_complement_many
from closedloop.kinematics import solve_dependent, solve_dependent_many
from closedloop import simulation
from closedloop.formulations.projected import PROJECTABLE_METHODS
from closedloop.simulation import dop853
from closedloop.slider_crank import SliderCrankParameters, get_case, initial_state
from closedloop.studies import benchmark, baseline


def test_every_list_of_methods_comes_from_one_place():
    assert simulation.SOLVER_METHODS == methods.SOLVER_METHODS
    assert methods.SOLVER_METHODS == ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA", "ode.dop853")
    assert dop853.METHOD == methods.COMPILED_METHOD
    assert list(PROJECTABLE_METHODS) == ["RK23", "RK45", "DOP853"]
    assert baseline.BASELINE_METHODS == methods.SOLVE_IVP_METHODS
    assert benchmark.ALL_METHODS == ("RK45", "DOP853", "Radau", "BDF", "LSODA", "ode.dop853")
    assert benchmark.EXPLICIT_RK == ("RK45", "DOP853")


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


@pytest.mark.parametrize("value", [5, 5.0, np.int64(5), np.float64(5.0), np.float32(5.0)])
def test_python_and_numpy_numbers_are_accepted_alike(value):
    assert validation.finite_number("step", value, minimum=0.0, strict=True) == 5.0
    assert isinstance(validation.positive_number("t_end", value), float)
    assert SliderCrankParameters(m3=value).m3 == value


@pytest.mark.parametrize("value", [np.int64(5), 5, np.int32(5)])
def test_numpy_integers_are_integers(value):
    assert validation.positive_integer("n_steps", value) == 5
    assert type(validation.positive_integer("n_steps", value)) is int


@pytest.mark.parametrize("value, shown", [(True, "True"), ("5", "'5'"), (None, "None"), (np.bool_(True), "True")])
def test_bool_text_and_none_are_refused_with_the_parameter_named(value, shown):
    with pytest.raises(InputError, match=rf"^step: must be a finite number > 0 s, got {shown}$"):
        validation.positive_number("step", value, unit="s")
    with pytest.raises(InputError, match=rf"^n_steps: must be an integer >= 1, got {shown}$"):
        validation.positive_integer("n_steps", value)
    with pytest.raises(InputError, match=r"^alpha: must be a finite number >= 0, got "):
        Baumgarte(alpha=value)


def test_each_message_names_the_range_and_the_value():
    with pytest.raises(InputError, match=r"^g: must be a finite number >= 0 m/s\^2, got -9\.81$"):
        SliderCrankParameters(g=-9.81)
    with pytest.raises(InputError, match=r"^step: must be a finite number > 0 s, got nan$"):
        validation.positive_number("step", np.float64("nan"), unit="s")
    with pytest.raises(InputError, match=r"^workers: must be an integer from 1 to 8, got 9$"):
        validation.integer("workers", 9, minimum=1, maximum=8)
    with pytest.raises(InputError, match=r"^x: must be a finite number from 0 to 1, got 1\.5$"):
        validation.finite_number("x", 1.5, minimum=0.0, maximum=1.0)
    with pytest.raises(InputError, match=r"^basis: unknown 'lu'; choose one of svd, pivoted$"):
        validation.one_of("basis", "lu", ("svd", "pivoted"))
    with pytest.raises(InputError, match=r"^case: unknown \[1\]; choose one of 1, 2, 3, 4$"):
        get_case([1])                                   # unhashable: refused, not a TypeError
    with pytest.raises(InputError, match=r"^q0: need 1 values, got 2$"):
        validation.finite_array("q0", [1.0, 2.0], size=1)
    assert validation.finite_number("x", 1.0, minimum=0.0, maximum=1.0) == 1.0   # both bounds: closed
    assert get_case(np.int64(2)).phi0 == math.pi / 2


def test_numpy_numbers_reach_the_library_unrefused(slider_crank):
    rule = baumgarte_from_step(np.float64(0.01))
    assert (rule.alpha, rule.beta) == pytest.approx((100.0, 100.0 * math.sqrt(2.0)))
    state = initial_state(slider_crank, np.float64(math.pi), np.int64(1))
    assert state.sd[0] == 1.0 and state.s[2] == pytest.approx(1.5, abs=1e-14)   # x_C = l2 - l1 at phi = pi


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


def test_the_energy_bookkeeping_refuses_another_system(slider_crank):
    from closedloop.studies.energy import crank_landscape

    values = dict(zip(map(str, slider_crank.model.parameters), slider_crank.parameter_values))
    plain = System(slider_crank.model, values)
    with pytest.raises(InputError, match=r"^system: expected a SliderCrankSystem, got System$"):
        crank_landscape(plain, [0.0, 1.0])
    assert crank_landscape(slider_crank, [0.0, 1.0]).slope[0] == pytest.approx(0.0, abs=1e-14)  # x_C' = 0 at phi = 0
