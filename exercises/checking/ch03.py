"""Checks for exercises/03-baumgarte.md."""

import numpy as np

from closedloop import Baumgarte, baumgarte_from_step, baumgarte_p2, simulate
from closedloop.slider_crank import CASES, initial_state, slider_crank_system

from . import Check, another_letter, as_numbers, choice, make_check, numeric, scaled

#: alpha, beta of exercise 3.5 (overdamped).
ROOT_GAINS = (5.0, 4.0)
#: alpha, beta of exercise 3.6.  The spoiled state has f' = 5 f, so only 10 alpha + beta^2 enters (17):
#: it must differ from 10 beta + alpha^2, or the gains swapped would pass (2, 8 and 8, 2 both give 84).
P2_GAINS = (3.0, 8.0)
#: The step of exercises 3.7 and 3.8 [s].
STEP = 0.01


def same_roots(rtol=1e-6, atol=1e-9):
    """Compare two sets of (possibly complex) roots, in any order."""
    def compare(answer, expected):
        answer, expected = as_numbers(answer, expected, complex_numbers=True), np.asarray(expected, dtype=complex)
        return bool(np.allclose(np.sort_complex(answer), np.sort_complex(expected), rtol=rtol, atol=atol))
    return compare


def _roots():
    alpha, beta = ROOT_GAINS
    return np.roots([1.0, 2.0 * alpha, beta**2])


def _spoiled_p2():
    system = slider_crank_system()
    state = initial_state(system, 2.0, 1.5)
    s = state.s + np.array([0.0, 0.0, 2e-3])
    sd = state.sd + np.array([0.0, 0.0, 1e-2])
    _, _, f, Phi, Phi_rate_sd = system.dynamics(0.0, s, sd)
    return baumgarte_p2(Phi, Phi_rate_sd, f, sd, *P2_GAINS)


def _step_rule_gains():
    rule = baumgarte_from_step(STEP)
    return [rule.alpha, rule.beta]


def _rule_against_baumgarte():
    system = slider_crank_system()
    case = CASES[4]
    start = initial_state(system, case.phi0, case.dphi0)
    times = np.linspace(0.0, 20.0, 2001)
    baumgarte, rule = (simulate(system, start, 20.0, formulation=formulation, method="RK45",
                                rtol=1e-6, atol=1e-6, t_eval=times)
                       for formulation in (Baumgarte(5.0, 5.0), baumgarte_from_step(STEP)))
    return [baumgarte.max_constraint_error / rule.max_constraint_error, rule.nfev / baumgarte.nfev]


def _critical_kick_response(alpha=5.0, kick=1.0):
    """Classify the solution of (15) with alpha = beta, e(0) = 0, e'(0) = kick, sampled in closed form.

    The double root mu = -alpha gives e(t) = (e0 + (e0' + alpha e0) t) exp(-alpha t).
    """
    e0 = 0.0
    times = np.linspace(0.0, 20.0 / alpha, 4001)[1:]
    error = (e0 + (kick + alpha * e0) * times) * np.exp(-alpha * times)
    changes_sign = bool(np.any(np.sign(error[1:]) != np.sign(error[:-1])))
    rate_sign = np.sign(np.diff(error))
    turning_points = int(np.count_nonzero(rate_sign[1:] != rate_sign[:-1]))
    if changes_sign:
        return "b"                                     # oscillates about zero
    if turning_points == 1 and abs(error[-1]) < 1e-3 * error.max():
        return "a"                                     # one peak, then decays without a sign change
    return "c"


CHECKS = {
    "3.5": Check("3.5", _roots, same_roots(),
                 "put f_i = exp(mu t) into one component of (15) and solve the quadratic for mu; "
                 "with alpha > beta both roots are real.",
                 lambda expected: np.asarray(expected) * 2.0),
    "3.6": Check("3.6", _spoiled_p2, numeric(1e-6, 1e-9),
                 "(17) has three terms. Phi_s s' is f', and system.dynamics returns the product "
                 "Phi_s' s' (not Phi_s'); mind the signs and the square on beta.",
                 scaled()),
    "3.7": Check("3.7", _step_rule_gains, numeric(1e-9, 0.0),
                 "the rule ties both gains to the step; give [alpha, beta] in 1/s, alpha first.",
                 scaled()),
    "3.8": Check("3.8", _rule_against_baumgarte, numeric(5e-2, 0.0),
                 "run both formulations with the same method, tolerances and t_eval; the first number is "
                 "max |f| of Baumgarte(5, 5) over that of the rule, the second nfev of the rule over "
                 "that of Baumgarte(5, 5).",
                 scaled()),
    "3.9": Check("3.9", _critical_kick_response, choice,
                 "a double root mu of the characteristic equation of (15) gives the solutions exp(mu t) "
                 "and t exp(mu t); fit their combination to the two initial conditions and sketch it.",
                 another_letter()),
}

check = make_check(CHECKS)
