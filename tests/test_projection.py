"""The projection method: every step back on f = 0 and f' = 0, through the gas-force switches."""

import numpy as np
import pytest

from closedloop import Augmented, ConvergenceError, InputError, Minimal, Projected, project_state, simulate
from closedloop.slider_crank import CASES, initial_state, slider_crank_system

NEWTON_LEVEL = 1e-13          # Newton's tolerance 1e-15 (1 + |s|), with |s| up to about 20 rad in 20 s


@pytest.fixture(scope="module")
def case2(slider_crank):
    case = CASES[2]
    return initial_state(slider_crank, case.phi0, case.dphi0)


def test_projection_is_the_minimum_norm_correction(slider_crank):
    rng = np.random.default_rng(5)
    state = initial_state(slider_crank, 1.0, 0.7)
    for _ in range(5):
        s = state.s + 1e-4 * rng.normal(size=3)
        sd = state.sd + 1e-2 * rng.normal(size=3)
        s_new, sd_new = project_state(slider_crank, s, sd)
        f, Phi = slider_crank.constraints_and_jacobian(s_new)
        assert np.abs(f).max() < 1e-14
        assert np.abs(Phi @ sd_new).max() < 1e-13
        R = slider_crank.orthogonal_complement(s_new)            # spans the null space of Phi_s (18)
        # the position correction is normal to the manifold up to its curvature, O(|ds|^2)
        assert np.abs(R.T @ (s_new - s)).max() < 1e-6
        # the velocity correction is exactly normal: an orthogonal projection, so it is idempotent
        assert np.abs(R.T @ (sd_new - sd)).max() < 1e-13
        again = project_state(slider_crank, s_new, sd_new)
        assert np.allclose(again[0], s_new, atol=1e-15) and np.allclose(again[1], sd_new, atol=1e-14)


@pytest.mark.parametrize("t_eval", [None, np.linspace(0.0, 20.0, 401)], ids=["steps", "dense output"])
def test_every_reported_state_is_on_the_manifold(slider_crank, case2, t_eval):
    projected = simulate(slider_crank, case2, 20.0, formulation=Projected(), method="RK45", rtol=1e-6,
                         atol=1e-6, t_eval=t_eval)
    drifting = simulate(slider_crank, case2, 20.0, formulation=Augmented(), method="RK45", rtol=1e-6,
                        atol=1e-6, t_eval=t_eval)
    assert len(projected.switch_events) >= 10                   # the gas force switched on the way
    assert projected.max_constraint_error < NEWTON_LEVEL
    assert projected.velocity_constraint_error.max() < NEWTON_LEVEL
    assert drifting.max_constraint_error > 1e-5                 # the same equations without projection drift (13)


def test_accuracy_converges_to_the_reference(slider_crank, case2):
    times = np.linspace(0.0, 20.0, 201)
    reference = simulate(slider_crank, case2, 20.0, formulation=Minimal(), method="DOP853", rtol=1e-12,
                         atol=1e-12, t_eval=times)
    ref = np.vstack((reference.s, reference.sd))
    errors = []
    for tol in (1e-5, 1e-7, 1e-9):
        run = simulate(slider_crank, case2, 20.0, formulation=Projected(), method="DOP853", rtol=tol, atol=tol,
                       t_eval=times)
        errors.append(np.abs(np.vstack((run.s, run.sd)) - ref).max())
    assert errors[1] < errors[0] / 20 and errors[2] < errors[1] / 20
    assert errors[2] < 1e-6


@pytest.mark.parametrize("method", ["Radau", "BDF", "LSODA"])
def test_methods_that_cannot_be_reset_are_refused(slider_crank, case2, method):
    with pytest.raises(InputError, match="projected formulation needs an explicit Runge-Kutta method.*RK45"):
        simulate(slider_crank, case2, 1.0, formulation=Projected(), method=method)


def test_a_tolerance_below_floating_point_is_named_not_blamed_on_the_integrator():
    """Newton reaches |f| ~ 1e-16 and stalls there: the message says so, not "left the manifold too far"."""
    system = slider_crank_system()
    state = initial_state(system, 1.0, 1.0)
    with pytest.raises(ConvergenceError, match=r"stalled at \|f\| = .* with a larger tolerance, e\.g\. ") as error:
        project_state(system, state.s + [0.0, 1e-3, 0.0], state.sd, 0.5, tolerance=1e-20)
    assert "too far" not in str(error.value)
    suggested = float(str(error.value).rsplit("e.g. ", 1)[1])          # the remedy it names works
    s, _ = project_state(system, state.s + [0.0, 1e-3, 0.0], state.sd, 0.5, tolerance=suggested)
    assert suggested < 1e-13 and np.max(np.abs(system.constraints(s))) <= suggested * (1 + np.max(np.abs(s)))
    with pytest.raises(ConvergenceError, match=r"\(\|f\| = 0\.7.*left the constraint manifold too far"):
        project_state(system, state.s + [0.0, 1.0, 0.5], state.sd, 0.5, max_iterations=2)
