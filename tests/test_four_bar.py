"""A parallelogram four-bar: it passes change points, where every link lies on the x axis."""

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

from closedloop import (Minimal, Orthogonal, SingularConfigurationError, System, consistent_initial_state,
                        derive, simulate)
from closedloop.examples import four_bar_model, parameter_values
from closedloop.kinematics import solve_dependent
from closedloop.plotting import animate_four_bar, four_bar_points

DATA = {"l0": 3.0, "l1": 1.0, "l2": 3.0, "l3": 1.0, "m1": 1.0, "m2": 2.0, "m3": 1.0, "g": 9.81}


@pytest.fixture(scope="module")
def parallelogram():
    return System(four_bar_model(), DATA)


@pytest.fixture(scope="module")
def run(parallelogram):
    """Over the top at 2 rad/s: the crank turns and passes theta1 = pi, 2 pi, ... (change points)."""
    start = consistent_initial_state(parallelogram, [np.pi / 2], [2.0], [0.0, np.pi / 2])
    t = np.linspace(0.0, 5.0, 1001)
    return start, simulate(parallelogram, start, 5.0, formulation=Minimal(), method="DOP853",
                           rtol=1e-11, atol=1e-11, t_eval=t)


def test_phi_z_determinant_vanishes_exactly_at_the_change_point(parallelogram):
    theta1, theta2, theta3 = four_bar_model().coordinates
    jacobian = derive(four_bar_model()).jacobian
    l2, l3 = sp.symbols("l2 l3")
    det = sp.simplify(jacobian[:, 1:].det())
    assert sp.simplify(det - l2 * l3 * sp.sin(theta2 - theta3)) == 0
    assert DATA["l0"] + DATA["l1"] == DATA["l2"] + DATA["l3"]          # Grashof with equality
    folded = solve_dependent(parallelogram, [0.0], [0.05, -0.05])      # theta1 = 0: all links on the x axis
    f, Phi = parallelogram.constraints_and_jacobian(folded)
    assert np.max(np.abs(f)) < 1e-12 and np.max(np.abs(folded[1:])) < 1e-6
    assert np.linalg.det(Phi[:, 1:]) == pytest.approx(0.0, abs=1e-6)
    assert np.linalg.matrix_rank(parallelogram.jacobian(np.zeros(3))) == 1   # Phi_s loses rank too
    assert np.linalg.det(parallelogram.jacobian(np.zeros(3))[:, 1:]) == 0.0


@pytest.mark.parametrize("theta", [0.0, np.pi])
def test_plain_r_at_the_change_point_is_a_clear_error(parallelogram, theta):
    s = np.array([theta, 0.0, theta])
    with pytest.raises(SingularConfigurationError, match=r"Phi_z is singular.*cond\(Phi_z\) = "):
        parallelogram.orthogonal_complement(s)
    with pytest.raises(SingularConfigurationError, match=r"at t = 0.5 s"):
        Orthogonal().accelerations(parallelogram, 0.5, s, np.array([1.0, 0.0, 1.0]))
    near = parallelogram.orthogonal_complement(np.array([theta + 1e-6, 0.0, theta + 1e-6]))
    assert np.allclose(near[:, 0], [1.0, 0.0, 1.0], atol=1e-9)          # off the point, R exists


def test_minimal_run_stays_closed_on_its_branch_and_matches_the_pendulum(parallelogram, run):
    start, result = run
    crank = result.coordinate("theta1")
    assert crank[-1] - crank[0] > 4 * np.pi                            # several change points passed
    assert result.max_constraint_error < 1e-12
    assert np.max(np.abs(result.coordinate("theta2"))) < 1e-9          # the coupler keeps translating
    # On the parallelogram branch the crank is a compound pendulum: I theta'' = -c g cos theta.
    m1, m2, m3, l1, l3, g = (DATA[k] for k in ("m1", "m2", "m3", "l1", "l3", "g"))
    inertia = m1 * l1**2 / 3 + m2 * l1**2 + m3 * l3**2 / 3
    moment = (m1 * l1 / 2 + m2 * l1 + m3 * l3 / 2) * g
    reference = solve_ivp(lambda t, y: [y[1], -moment / inertia * np.cos(y[0])], (0.0, 5.0),
                          [np.pi / 2, 2.0], method="DOP853", rtol=1e-12, atol=1e-12, t_eval=result.t)
    assert np.max(np.abs(reference.y[0] - crank)) < 1e-7


def test_unforced_four_bar_conserves_energy_through_change_points(parallelogram, run):
    start, result = run
    energy = parallelogram.energy(result.s, result.sd)
    initial = parallelogram.energy(start.s, start.sd)
    assert abs(initial) > 10.0
    assert np.max(np.abs(energy - initial)) / abs(initial) < 1e-9


def test_four_bar_drawing_closes_the_loop_and_animates(parallelogram, run):
    _, result = run
    lengths = parameter_values(parallelogram)
    points = four_bar_points(result.s[:, 123], lengths)
    assert np.linalg.norm(points[2] - points[3]) == pytest.approx(DATA["l3"], abs=1e-9)   # |BD| = l3
    html = animate_four_bar(result, lengths, frames=5)
    assert html.count("data:image/png;base64") == 5 and "maxcdn" not in html
