"""Checks for exercises/02-lagrange-multipliers.md."""

import numpy as np
import sympy as sp

from closedloop import Augmented, derive, simulate
from closedloop.slider_crank import CASES, initial_state, slider_crank_model, slider_crank_system

from . import Check, choice, make_check, numeric, scaled, symbolic

#: phi, phi' of the state in exercises 2.5 and 2.6: crank pointing down, slider moving outward.
OUTWARD = (3.0 * np.pi / 2.0, 1.0)



def _flip_coupling(mass_matrix):
    """M with the wrong sign on the crank-rod coupling."""
    wrong = sp.Matrix(mass_matrix)
    wrong[0, 1], wrong[1, 0] = -wrong[0, 1], -wrong[1, 0]
    return wrong


def _mass_matrix():
    return derive(slider_crank_model()).mass_matrix


def _outward_solution():
    system = slider_crank_system()
    state = initial_state(system, *OUTWARD)
    return system.constrained_accelerations(0.0, state.s, state.sd)


def _drift_case_4():
    system = slider_crank_system()
    case = CASES[4]
    result = simulate(system, initial_state(system, case.phi0, case.dphi0), 20.0, formulation=Augmented(),
                      method="RK45", rtol=1e-6, atol=1e-6)
    return result.max_constraint_error


CHECKS = {
    "2.4": Check("2.4", _mass_matrix, symbolic(),
                 "M_ij is the second derivative of T with respect to the i-th and j-th velocities: a cross "
                 "term c phi' psi' of T gives c to both M_12 and M_21. Keep every symbol of T, even those "
                 "that Table 1 sets to zero.",
                 _flip_coupling),
    "2.5": Check("2.5", lambda: _outward_solution()[0], numeric(1e-6, 1e-9),
                 "the matrix is [[M, Phi_s^T], [Phi_s, 0]], the right-hand side [p1; p2] with "
                 "p2 = -(Phi_s' s') of (11); the first n entries of the solution are s''.",
                 scaled()),
    "2.6": Check("2.6", lambda: _outward_solution()[1][0], numeric(1e-6, 1e-9),
                 "the slider's row of (8) involves only the third column of Phi_s; which entries of it "
                 "are not zero, and with which sign does lambda_1 appear?",
                 scaled()),
    # 0.5 %: the largest |f| is at t = 20 s, the same with any outputs; case 1's is 1.7 % off case 4's
    "2.7": Check("2.7", _drift_case_4, numeric(5e-3, 0.0),
                 "integrate (12) with Augmented() for 20 s from case 4's consistent initial state, RK45 "
                 "with rtol = atol = 1e-6, and take the largest |f| of (32) over the run.",
                 scaled()),
    "2.8": Check("2.8", lambda: "c", choice,
                 "the differentiation index counts the time differentiations needed until every unknown, "
                 "the multipliers included, obeys an ODE. Apply that definition to the unknowns s, v and "
                 "lambda of (12) as posed.",
                 lambda expected: "b"),
}

check = make_check(CHECKS)
