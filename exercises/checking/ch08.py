"""Checks for exercises/08-error-vs-runtime.md."""

import numpy as np
import sympy as sp

from closedloop import Augmented, Minimal, Projected, derive, project_state, simulate
from closedloop.studies.benchmark import DEFAULT_SETTINGS, study_entries
from closedloop.slider_crank import CASES, initial_state, slider_crank_model, slider_crank_system

from . import Check, another_letter, choice, make_check, numeric, scaled, symbolic

#: The case of every run here: the study's main case.
CASE = 2
#: The spoiling of case 2's configuration in exercise 8.8: [phi, psi, x_C].
SPOIL = (0.0, 1e-2, 1e-2)
#: The drift that exercise 8.9 allows [m], and the ladder of tolerances it tries.
DRIFT_LIMIT = 1e-6
LADDER = tuple(10.0**-k for k in range(3, 11))
#: The study's common output grid (8.d).
GRID = np.linspace(0.0, 20.0, 2001)


def _start():
    system = slider_crank_system()
    case = CASES[CASE]
    return system, initial_state(system, case.phi0, case.dphi0)


def _curves_in_main_case():
    methods = DEFAULT_SETTINGS.methods_of(DEFAULT_SETTINGS.main_case)
    return sum(sum(method in entry.methods for method in methods) for entry in study_entries())


def _error_at_ten_seconds():
    """e10 of (8.c): Augmented, DOP853, 1e-6 against Minimal, DOP853, 1e-12, output at 10 and 20 s."""
    system, state = _start()
    run, reference = (simulate(system, state, 20.0, formulation=formulation, method="DOP853", rtol=tol,
                               atol=tol, t_eval=[10.0, 20.0])
                      for formulation, tol in ((Augmented(), 1e-6), (Minimal(), 1e-12)))
    return np.abs(np.vstack((run.s, run.sd))[:, 0] - np.vstack((reference.s, reference.sd))[:, 0]).max()


def _gram_determinant():
    jacobian = derive(slider_crank_model()).jacobian
    return sp.simplify((jacobian * jacobian.T).det())


def _without_a_minor(expected):
    """A wrong determinant: the minor of the columns of psi and x_C left out."""
    psi, l2 = sp.Symbol("psi"), sp.Symbol("l2")
    return expected - l2**2 * sp.cos(psi)**2


def _projected_positions():
    system, state = _start()
    return project_state(system, state.s + np.array(SPOIL), state.sd)[0]


def _loosest_tolerance():
    system, state = _start()
    for tol in sorted(LADDER, reverse=True):         # loose to tight: the first that meets the limit is the loosest
        if simulate(system, state, 20.0, formulation=Augmented(), method="DOP853", rtol=tol, atol=tol,
                    t_eval=GRID).max_constraint_error <= DRIFT_LIMIT:
            return tol
    raise AssertionError(f"no tolerance of {LADDER} keeps max |f| <= {DRIFT_LIMIT}")


def _output_cost():
    """Compare the steps and nfev of Projected runs with the 2001-point grid and with two outputs."""
    system, state = _start()
    dense, sparse = (simulate(system, state, 20.0, formulation=Projected(), method="DOP853", rtol=1e-6,
                              atol=1e-6, t_eval=times) for times in (GRID, [10.0, 20.0]))
    if not np.array_equal(dense.step_sizes, sparse.step_sizes):
        return "a"
    return "b" if dense.nfev > sparse.nfev else "c"


CHECKS = {
    "8.5": Check("8.5", _curves_in_main_case, numeric(0, 0),
                 "for each entry of study_entries(), count the methods of DEFAULT_SETTINGS.methods_of(2) "
                 "that are also in the entry's own methods, and add up.",
                 lambda expected: expected + 4),
    "8.6": Check("8.6", _error_at_ten_seconds, numeric(2e-2, 0),
                 "y has six rows, s on top of sd; take the largest absolute difference from the reference "
                 "at t = 10 s, with both runs going to 20 s and reporting at 10 and 20 s.",
                 scaled()),
    "8.7": Check("8.7", _gram_determinant, symbolic(),
                 "Phi_s has three columns, so three 2 x 2 minors; square each one and add them. Check "
                 "the signs of the entries of Phi_s by differentiating (27) and (28).",
                 _without_a_minor),
    "8.8": Check("8.8", _projected_positions, numeric(1e-9, 1e-12),
                 "subtract Phi_s^T (Phi_s Phi_s^T)^{-1} f(s) from all three coordinates at every iteration, "
                 "with Phi_s and f at the current s; start from the spoiled s, not the consistent one.",
                 scaled()),
    "8.9": Check("8.9", _loosest_tolerance, numeric(1e-6, 0),
                 "run every tolerance of the ladder with t_eval on the 2001-point grid, keep those whose "
                 "max_constraint_error is at most 1e-6, and give the largest of them.",
                 lambda expected: 10.0 * expected),
    "8.10": Check("8.10", _output_cost, choice,
                 "compare the two runs' step_sizes with np.array_equal, then their nfev.",
                 another_letter()),
}

check = make_check(CHECKS)
