"""Checks for exercises/13-four-bar.md."""

import math

import numpy as np
import sympy as sp

from closedloop import (Minimal, NullSpace, SingularConfigurationError, System, consistent_initial_state, derive,
                        simulate)
from closedloop.four_bar import four_bar_model, parameter_values

from . import Check, another_letter, choice, make_check, numeric, same_angles, scaled, symbolic

#: The chapter's parallelogram [m], [kg], [m/s^2].
DATA = {"l0": 3.0, "l1": 1.0, "l2": 3.0, "l3": 1.0, "m1": 1.0, "m2": 2.0, "m3": 1.0, "g": 9.81}
#: The lengthened base of exercise 13.6 and the shortened crank of exercise 13.8 [m].
ROCKING_BASE = 3.2
SHORTER_CRANK = 0.9
#: Exercise 13.7: released from rest at this crank angle, stopped at the second one [rad].
FALL = (0.3, 0.05)


def _crossed_assembly():
    """The anti-parallelogram at theta1 = pi/2: Newton from a guess far from the parallelogram."""
    system = System(four_bar_model(), DATA)
    state = consistent_initial_state(system, [math.pi / 2], [0.0], [-0.5, -2.0])
    return state.s[1:]


def _R_closed_form():
    """R of (20) for q = [theta1], from the derived Jacobian."""
    model = four_bar_model()
    jacobian = derive(model).jacobian
    Phi_q, Phi_z = jacobian[:, model.independent_index.tolist()], jacobian[:, model.dependent_index.tolist()]
    return sp.simplify(sp.Matrix.vstack(sp.eye(1), -Phi_z.LUsolve(Phi_q)))


def _swap_rows(expected):
    """R with the rows of theta2 and theta3 swapped."""
    return sp.Matrix([expected[0], expected[2], expected[1]])


def _dead_position_accelerations():
    """s'' from NullSpace(5, 5) at the rocking linkage's dead position, at rest.

    theta1 is the angle at O of the triangle OAD with |AD| = l2 + l3; coupler and rocker lie on AD.
    """
    system = System(four_bar_model(), dict(DATA, l0=ROCKING_BASE))
    values = parameter_values(system)
    l0, l1, l2, l3 = (values[name] for name in ("l0", "l1", "l2", "l3"))
    limit = math.acos((l0**2 + l1**2 - (l2 + l3)**2) / (2 * l0 * l1))
    pin = l1 * np.array([math.cos(limit), math.sin(limit)])
    coupler = math.atan2(-pin[1], l0 - pin[0])
    s = np.array([limit, coupler, coupler + math.pi])
    if np.linalg.norm(system.constraints(s)) > 1e-12:
        raise ValueError("the dead position does not close the loop")
    return NullSpace(5, 5).accelerations(system, 0.0, s, np.zeros(3))


def _fall_time():
    system = System(four_bar_model(), DATA)
    start, stop = FALL
    resting = consistent_initial_state(system, [start], [0.0], [0.0, start])
    result = simulate(system, resting, 5.0, formulation=NullSpace(5, 5), method="DOP853", rtol=1e-10, atol=1e-10,
                      stop_when=lambda t, s, sd: stop - s[0])
    return result.stopped_at


def _shorter_crank():
    """'a' if Phi_s loses rank over a turn, 'b' if only Phi_z does (or Minimal stops), else 'c'."""
    system = System(four_bar_model(), dict(DATA, l1=SHORTER_CRANK))
    dependent, rank_ratio, condition = [0.0, math.pi / 2], [], []
    for angle in np.linspace(0.0, 2 * math.pi, 721):
        dependent = consistent_initial_state(system, [angle], [0.0], dependent).s[1:]
        Phi = system.jacobian(np.concatenate(([angle], dependent)))
        singular_values = np.linalg.svd(Phi, compute_uv=False)
        rank_ratio.append(singular_values[-1] / singular_values[0])
        condition.append(np.linalg.cond(Phi[:, 1:]))
    if min(rank_ratio) < 1e-6:
        return "a"
    if max(condition) > 1e6:
        return "b"
    try:
        start = consistent_initial_state(system, [math.pi / 2], [2.0], [0.0, math.pi / 2])
        result = simulate(system, start, 5.0, formulation=Minimal(), method="DOP853", rtol=1e-9, atol=1e-9)
    except SingularConfigurationError:
        return "b"
    return "c" if result.coordinate("theta1")[-1] > math.pi / 2 + 2 * math.pi else "b"


CHECKS = {
    "13.4": Check("13.4", _crossed_assembly, same_angles(),
                  "with the crank upright, A = (0, l1); write |AB| = l2 with B on the rocker's circle about D, "
                  "and keep the solution that is not the parallelogram.",
                  lambda expected: np.asarray(expected) + 0.5),
    "13.5": Check("13.5", _R_closed_form, symbolic(),
                  "the first entry is 1 (theta1 itself); solve Phi_z [theta2', theta3'] = -Phi_q theta1' and "
                  "keep the rows in the order theta1, theta2, theta3.",
                  _swap_rows),
    "13.6": Check("13.6", _dead_position_accelerations, numeric(1e-6, 1e-8),
                  "B lies on the segment AD at distance l2 from A, so theta2 is the direction of D - A and "
                  "theta3 = theta2 + pi; at rest p2~ of (17) keeps only its -beta^2 f term.", scaled()),
    "13.7": Check("13.7", _fall_time, numeric(1e-5, 0),
                  "stop_when must cross zero upward as the crank falls: its value should grow as theta1 "
                  "decreases. The run starts from rest on the parallelogram branch.", scaled()),
    "13.8": Check("13.8", _shorter_crank, choice,
                  "coupler and rocker line up only where |AD| = l2 + l3 or l2 - l3; which values does |AD| "
                  "take as the crank turns?",
                  another_letter()),
}

check = make_check(CHECKS)
