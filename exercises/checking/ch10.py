"""Checks for exercises/10-singularities-and-switches.md."""

import math

import numpy as np
import sympy as sp

from closedloop import Baumgarte, InitialState, derive, simulate
from closedloop.slider_crank import (SliderCrankParameters, initial_state, slider_crank_model,
                                     slider_crank_system)

from . import Check, choice, make_check, not_an_expression, numeric, scaled

#: The rocking crank of the chapter: l2 = 1.5 m < l1 = 2 m, centre of mass mid-rod.
ROCKING = SliderCrankParameters(l2=1.5, a2=0.75, full_rotation=False)
#: Exercise 10.6: the rod ratio l2/l1 and the slider's displacement off the constraint [m].
NEAR_RATIO, SLIDER_SHIFT = 1.001, 1e-4
#: Exercise 10.8: the rod ratio of configuration (iii), and the thresholds that define the answer.
CLOSE_RATIO, SINGULAR_PARTITION, NEAR_RANK_LOSS = 1.00001, 1e8, 100.0
#: Exercise 10.9: the start at rest with the crank pin up, and the horizon [s].
REST_START, STICK_HORIZON = (math.pi / 2, 0.0), 20.0


def _rod_system(ratio, l1=2.0):
    """Table 1 with l2 = ratio * l1 (centre of mass mid-rod), no torque, no gas force."""
    return slider_crank_system(SliderCrankParameters(l2=ratio * l1, a2=ratio * l1 / 2,
                                                     full_rotation=ratio > 1), torque=False, gas=False)


def _curvature():
    """d^2 psi / d phi^2 at phi = pi/2 on the paper's branch, from the derived Jacobian."""
    derived = derive(slider_crank_model())
    Phi = derived.jacobian
    q_index, z_index = derived.model.independent_index, derived.model.dependent_index
    slope = -Phi[:, list(z_index)].inv() * Phi[:, list(q_index)]          # z' = slope q' (20)
    phi, psi, x = derived.model.coordinates
    rates = {phi: 1, psi: slope[0], x: slope[1]}
    along_branch = sum(sp.diff(slope[0], coordinate) * rate for coordinate, rate in rates.items())
    l1, l2 = (next(p for p in derived.model.parameters if str(p) == name) for name in ("l1", "l2"))
    top = {phi: sp.pi / 2, psi: sp.pi - sp.asin(l1 / l2)}                  # (28), cos psi < 0
    return sp.simplify(along_branch.subs(top))


def same_function_of_lengths(rtol=1e-9, points=6, seed=2018):
    """Compare sympy expressions in l1, l2 at random points with l2 > l1 (the paper's crank)."""
    def compare(answer, expected):
        not_an_expression(answer)                   # as symbolic(): sympify would take "abc" for a symbol
        answer = sp.sympify(answer)
        names = {str(symbol) for symbol in answer.free_symbols}
        if not names <= {"l1", "l2"}:
            return False
        rng = np.random.default_rng(seed)
        for _ in range(points):
            l1 = rng.uniform(0.5, 3.0)
            point = {"l1": l1, "l2": l1 * rng.uniform(1.01, 3.0)}
            values = [complex(expression.subs({s: point[str(s)] for s in expression.free_symbols}).evalf())
                      for expression in (answer, expected)]
            if abs(values[0].imag) > 1e-12 or not math.isclose(values[0].real, values[1].real, rel_tol=rtol):
                return False
        return True
    return compare


def _kantorovich():
    """h of (10.b) at the consistent configuration phi = pi/2, l2 = 1.001 l1, with x_C moved 0.1 mm."""
    system = _rod_system(NEAR_RATIO)
    s = initial_state(system, math.pi / 2, 0.0).s + np.array([0.0, 0.0, SLIDER_SHIFT])
    singular_values = np.linalg.svd(system.jacobian(s), compute_uv=False)
    return singular_values[0] * np.linalg.norm(system.constraints(s)) / singular_values[-1] ** 2


def _dead_position_state():
    """The rocking crank at rest at phi = pi - asin(l2/l1), rod upright, psi' = 1 rad/s."""
    phi = math.pi - math.asin(ROCKING.l2 / ROCKING.l1)
    return InitialState([phi, math.pi / 2, ROCKING.l1 * math.cos(phi)], [0.0, 1.0, ROCKING.l2])


def _dead_position_accelerations():
    """s'' at the dead position from the augmented system (12): it needs no partition."""
    state = _dead_position_state()
    rocking = slider_crank_system(ROCKING, torque=False, gas=False)
    return rocking.constrained_accelerations(0.0, state.s, state.sd)[0]


def _classification():
    """'r' regular, 'd' dead position (cond Phi_z > 1e8, cond Phi_s < 100), 'b' cond Phi_s > 100."""
    paper, close = slider_crank_system(), _rod_system(CLOSE_RATIO)
    configurations = ((paper, initial_state(paper, math.pi / 2, 0.0).s),
                      (slider_crank_system(ROCKING, torque=False, gas=False), _dead_position_state().s),
                      (close, initial_state(close, math.pi / 2, 0.0).s))
    letters = ""
    for system, s in configurations:
        Phi = system.jacobian(s)
        if np.linalg.cond(Phi) > NEAR_RANK_LOSS:
            letters += "b"
        elif np.linalg.cond(Phi[:, system.z_index]) > SINGULAR_PARTITION:
            letters += "d"
        else:
            letters += "r"
    return letters


def _sticking_time():
    paper = slider_crank_system()
    result = simulate(paper, initial_state(paper, *REST_START), STICK_HORIZON, formulation=Baumgarte(10, 10),
                      method="DOP853", rtol=1e-10, atol=1e-10)
    return result.sticking_intervals[0][0]


CHECKS = {
    "10.5": Check("10.5", _curvature, same_function_of_lengths(),
                  "differentiate d psi/d phi = l1 cos(phi) / (l2 cos(psi)) once more, remembering that psi "
                  "depends on phi; at phi = pi/2 one term vanishes, and cos(psi) < 0 on the paper's branch. "
                  "Use only the symbols l1 and l2.",
                  lambda expected: -expected),
    "10.6": Check("10.6", _kantorovich, numeric(1e-6, 0.0),
                  "use the singular values of Phi_s at the spoiled state (not at the consistent one), "
                  "|f| as the 2-norm of both constraints, and square sigma_min.",
                  scaled()),
    "10.7": Check("10.7", _dead_position_accelerations, numeric(1e-6, 1e-9),
                  "N is the last right singular vector of Phi_s (V^T's last row); stack N^T M over Phi_s, "
                  "and N^T p1 over p2~ of (17), which at a consistent state is -Phi_s' s'. Give s'' in the "
                  "order [phi, psi, x_C].",
                  scaled()),
    "10.8": Check("10.8", _classification, choice,
                  "compute cond(Phi_s) and cond(Phi_z) at each configuration; Phi_z is the psi and x_C "
                  "columns. Near a bifurcation both are large; at a dead position only Phi_z is.",
                  lambda expected: expected[::-1]),
    "10.9": Check("10.9", _sticking_time, numeric(1e-5, 0.0),
                  "use switching='events' (the default) with a tolerance of 1e-6 or tighter, and give the "
                  "start of the first interval in result.sticking_intervals, in seconds.",
                  scaled()),
}

check = make_check(CHECKS)
