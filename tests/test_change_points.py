"""Change points: a parallelogram four-bar meets them where every link lies on the x axis.

At a change point Phi_s itself loses rank and two assembly branches meet (a bifurcation), so
every formulation must stop there with a clear error, at the time the crank reaches it.  The
reference for that time is the branch's own one-degree-of-freedom equation: on the
parallelogram the coupler only translates and the crank is a compound pendulum.
"""

import re

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

from closedloop import (Augmented, Baumgarte, ClosedForm, Minimal, NullSpace, Orthogonal, Projected,
                        SingularConfigurationError, System, consistent_initial_state, derive, simulate)
from closedloop.four_bar import four_bar_model
from closedloop.kinematics import solve_dependent
from closedloop.simulation.change_points import CHANGE_POINT_LIMIT

from .conftest import PARALLELOGRAM, SWINGING

DATA = PARALLELOGRAM
OVER_THE_TOP = (np.pi / 2, 2.0)          # crank angle [rad] and rate [rad/s]: it turns over


def pendulum(angle, rate, t_end, t_eval=None, events=None, data=DATA):
    """The parallelogram branch's own equation: I theta1'' = -c g cos theta1 (theta2 = 0, theta3 = theta1)."""
    m1, m2, m3, l1, l3, g = (data[k] for k in ("m1", "m2", "m3", "l1", "l3", "g"))
    inertia = m1 * l1**2 / 3 + m2 * l1**2 + m3 * l3**2 / 3
    moment = (m1 * l1 / 2 + m2 * l1 + m3 * l3 / 2) * g
    return solve_ivp(lambda t, y: [y[1], -moment / inertia * np.cos(y[0])], (0.0, t_end), [angle, rate],
                     method="DOP853", rtol=1e-12, atol=1e-12, t_eval=t_eval, events=events)


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
    with pytest.raises(SingularConfigurationError, match=r"Phi_z is singular.*\|Phi_s\| \|Phi_z\^-1\| = "):
        parallelogram.orthogonal_complement(s)
    with pytest.raises(SingularConfigurationError, match=r"at t = 0.5 s"):
        Orthogonal().accelerations(parallelogram, 0.5, s, np.array([1.0, 0.0, 1.0]))
    near = parallelogram.orthogonal_complement(np.array([theta + 1e-6, 0.0, theta + 1e-6]))
    assert np.allclose(near[:, 0], [1.0, 0.0, 1.0], atol=1e-9)          # off the point, R exists


@pytest.mark.parametrize("theta", [0.0, np.pi])
def test_null_space_refuses_the_change_point_itself(parallelogram, theta):
    """N of the null space needs Phi_s of full rank, which it is not where the branches meet."""
    with pytest.raises(SingularConfigurationError, match=r"Phi_s lost rank at t = 0.5 s: cond\(Phi_s\) = "):
        NullSpace().accelerations(parallelogram, 0.5, np.array([theta, 0.0, theta]), np.array([1.0, 0.0, 1.0]))


def _stop_time(error):
    return float(re.search(r"at t = ([0-9.e+-]+) s", str(error)).group(1))


def test_a_start_beside_a_change_point_is_stopped_at_once(parallelogram):
    """1e-9 rad past theta1 = pi, moving away: sigma_min(Phi_s) is smallest at the path's first point,
    which the check counts as a minimum (an interior one would have been missed: the run went on)."""
    theta = np.pi + 1e-9
    state = consistent_initial_state(parallelogram, [theta], [2.0], [0.0, theta])
    with pytest.raises(SingularConfigurationError, match="reaches a change point") as error:
        simulate(parallelogram, state, 1.0, formulation=Augmented(), method="DOP853", rtol=1e-10, atol=1e-10)
    assert _stop_time(error.value) < 1e-9


#: Three parallelograms: the 3 x 1 one started OVER_THE_TOP (the crank reaches theta1 = pi at about
#: 0.517 s), and two that nobody here designed the guard for, the 2 x 1 one and the square one (all
#: links 1 m, where the crank can also fold onto the ground link), started with the crank vertical
#: and turning down at 1 rad/s (they reach theta1 = 0 at about 0.708 s).
CHANGE_POINTS = {
    "3x1": (DATA, OVER_THE_TOP, np.pi),
    "2x1": ({"l0": 2.0, "l1": 1.0, "l2": 2.0, "l3": 1.0, "m1": 1.0, "m2": 1.0, "m3": 1.0, "g": 9.81},
            (np.pi / 2, -1.0), 0.0),
    "square": ({"l0": 1.0, "l1": 1.0, "l2": 1.0, "l3": 1.0, "m1": 1.0, "m2": 1.0, "m3": 1.0, "g": 9.81},
               (np.pi / 2, -1.0), 0.0),
}
#: Every formulation on each runner it accepts: solve_ivp explicit and implicit, and the compiled DOP853.
PATHS = ([(formulation, "DOP853") for formulation in (Augmented(), Baumgarte(5, 5), Orthogonal(5, 5),
                                                      NullSpace(5, 5), ClosedForm(5, 5), Projected(), Minimal())]
         + [(formulation, "Radau") for formulation in (Augmented(), Baumgarte(5, 5), Orthogonal(5, 5),
                                                       NullSpace(5, 5), ClosedForm(5, 5), Minimal())]
         + [(formulation, "ode.dop853") for formulation in (Orthogonal(5, 5), ClosedForm(5, 5), Minimal())])


#: Each path on each geometry, with outputs at the steps and every 5 ms; the implicit Radau, ten times
#: slower here, on the 3 x 1 parallelogram with dense outputs only.
RUNS = [pytest.param(formulation, method, geometry, outputs,
                     id=f"{formulation.name}-{method}-{geometry}-{outputs.replace(' ', '')}")
        for formulation, method in PATHS for geometry in CHANGE_POINTS for outputs in ("steps", "every 5 ms")
        if method != "Radau" or (geometry, outputs) == ("3x1", "every 5 ms")]


@pytest.mark.parametrize("formulation, method, geometry, outputs", RUNS)
def test_every_path_stops_at_the_change_point(formulation, method, geometry, outputs):
    """Every formulation and runner stops where the exact pendulum of the branch reaches the fold.

    These were the holes: det Phi_z touches zero at the fold and keeps its sign, so a guard on its
    sign changes let Baumgarte + Radau and the compiled DOP853 with dense outputs go on, on the wrong
    branch, with a perfect |f|.  The check on sigma_min(Phi_s) along the steps sees it on every path.
    """
    data, (angle, rate), fold_angle = CHANGE_POINTS[geometry]
    system = System(four_bar_model(), data)
    fold = pendulum(angle, rate, 2.0, events=lambda t, y: y[0] - fold_angle, data=data).t_events[0][0]
    assert 0.5 < fold < 0.75
    start = consistent_initial_state(system, [angle], [rate], [0.0, angle])
    t_eval = np.linspace(0.0, 2.0, 401) if outputs == "every 5 ms" else None
    with pytest.raises(SingularConfigurationError, match="no formulation of this library passes a change point"
                       ) as caught:
        simulate(system, start, 2.0, formulation=formulation, method=method, rtol=1e-10, atol=1e-10,
                 t_eval=t_eval)
    message = str(caught.value)
    if "reaches a change point" in message:
        assert float(re.search(r"Kantorovich number (inf|[0-9.e+-]+)", message).group(1)) > CHANGE_POINT_LIMIT
    elif "crawls" in message:           # Radau creeps towards it, its steps shrinking to nothing
        assert method == "Radau" and float(re.search(r"cond\(Phi_s\) = ([0-9.e+-]+)", message).group(1)) > 1e3
    else:                               # the projection of a step end met the loss of rank first
        assert formulation.name == "projected" and "Phi_s Phi_s^T is singular" in message
    # Minimal stops when Newton fails one stage past the fold, and the fold is found on the
    # extrapolated step: within 5e-4 s; every other path within 1e-5 s.
    assert _stop_time(caught.value) == pytest.approx(fold, abs=5e-4 if formulation.name == "minimal" else 1e-5)


def test_swing_below_the_folds_stays_a_parallelogram_and_matches_the_pendulum(parallelogram_swing):
    start, result = parallelogram_swing
    crank = result.coordinate("theta1")
    assert -np.pi + 0.5 < crank.min() and crank.max() < -0.5             # never near 0 or -pi
    assert result.max_constraint_error < 1e-12
    assert np.max(np.abs(result.coordinate("theta2"))) < 1e-9          # the coupler keeps translating
    reference = pendulum(*SWINGING, 5.0, t_eval=result.t)
    assert np.max(np.abs(reference.y[0] - crank)) < 1e-7
    assert np.sum(np.diff(np.sign(result.velocity("theta1"))) != 0) >= 4   # several swings

