"""Checks for exercises/04-orthogonality.md."""

import dataclasses

import numpy as np
import sympy as sp

from closedloop import Baumgarte, Orthogonal, derive, simulate
from closedloop.slider_crank import CASES, initial_state, slider_crank_model, slider_crank_system

from . import Check, another_letter, choice, make_check, numeric, scaled, symbolic

#: The configuration of exercise 4.5: not on the constraint manifold (27)-(28).
OFF_MANIFOLD = (2.0, 2.9, 4.0)
#: The slider offset [m] of exercise 4.6, away from case 2's consistent start.
SLIDER_OFFSET = 1e-3


def entries(rtol, atol):
    """Compare arrays entry by entry, whatever their shape ((3,) or (3, 1))."""
    compare = numeric(rtol, atol)
    return lambda answer, expected: compare(np.ravel(answer), np.ravel(expected))



def _R_off_manifold():
    return slider_crank_system().orthogonal_complement(np.array(OFF_MANIFOLD))


def _perturbed_accelerations():
    system = slider_crank_system()
    state = initial_state(system, CASES[2].phi0, CASES[2].dphi0)
    s = state.s + np.array([0.0, 0.0, SLIDER_OFFSET])
    return Orthogonal(5, 5).accelerations(system, 0.0, s, state.sd)


def _det_Phi_z_with_psi_independent():
    model = slider_crank_model()
    psi_first = dataclasses.replace(model, independent=(model.coordinates[1],))
    jacobian = derive(psi_first).jacobian
    return sp.simplify(jacobian[:, list(psi_first.dependent_index)].det())


def _nfev_ratio():
    system = slider_crank_system()
    state = initial_state(system, CASES[2].phi0, CASES[2].dphi0)
    runs = [simulate(system, state, 10.0, formulation=formulation, method="RK45", rtol=1e-6, atol=1e-6)
            for formulation in (Orthogonal(5, 5), Baumgarte(5, 5))]
    return runs[0].nfev / runs[1].nfev


def _why_R_removes_multipliers():
    """Test (18) off the manifold, and whether the multipliers vanish along case 4's start."""
    system = slider_crank_system()
    s = np.array(OFF_MANIFOLD)
    off_manifold = np.abs(system.constraints(s)).max() > 1e-6
    product = system.orthogonal_complement(s).T @ system.jacobian(s).T
    if off_manifold and np.allclose(product, 0.0, atol=1e-10):
        return "c"                                    # (18) holds off the manifold too
    state = initial_state(system, CASES[4].phi0, CASES[4].dphi0)
    multipliers = system.constrained_accelerations(0.0, state.s, state.sd)[1]
    return "a" if np.allclose(multipliers, 0.0) else "b"


CHECKS = {
    "4.5": Check("4.5", _R_off_manifold, entries(1e-9, 1e-12),
                 "E goes in the row of phi; the rows of psi and x_C hold minus the solution of "
                 "Phi_z X = Phi_q. Did you keep the sign?",
                 lambda expected: -np.asarray(expected)),
    "4.6": Check("4.6", _perturbed_accelerations, numeric(1e-8, 1e-10),
                 "the lower rows of p are Baumgarte's p2~ of (17), with alpha = beta = 5 and the nonzero "
                 "f and Phi_s s' of this state; the upper rows are R^T p1.", scaled()),
    "4.7": Check("4.7", _det_Phi_z_with_psi_independent, symbolic(),
                 "Phi_z now holds the columns of phi and x_C, in that order; differentiate (27) and (28) "
                 "with respect to each.",
                 lambda expected: -expected),
    "4.8": Check("4.8", _nfev_ratio, numeric(1e-2, 0),
                 "divide the orthogonal run's nfev by the Baumgarte run's, both from the same state with the "
                 "same method and tolerances.", scaled()),
    "4.9": Check("4.9", _why_R_removes_multipliers, choice,
                 "in (22), lambda enters only through the term Phi_s^T lambda: think about which directions "
                 "that term can point in, and what R^T does to those directions.",
                 another_letter()),
}

check = make_check(CHECKS)
