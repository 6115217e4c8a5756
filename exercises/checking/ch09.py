"""Checks for exercises/09-stiffness-and-long-runs.md."""

import numpy as np
import sympy as sp
from scipy.optimize import brentq

from closedloop import Augmented, Baumgarte, Minimal, simulate
from closedloop.conditioning import conditioning, generalized_mass
from closedloop.fixed_step import rk4_baumgarte_growth, rk4_stability_function
from closedloop.slider_crank import CASES, SliderCrankParameters, initial_state, slider_crank_system

from . import Check, another_letter, choice, make_check, numeric, symbolic

#: alpha = beta of exercise 9.5 [1/s]: critical damping.
CRITICAL_GAIN = 1000.0
#: Exercise 9.6: the length of the run [s] and its output grid.
WORK_END = 5.0
WORK_TIMES = np.linspace(0.0, WORK_END, 5001)
#: The crank angle and speed of the configuration in exercise 9.7.
TEST_STATE = (2.0, 3.0)


def _spread(m1, m2, m3):
    """The mass spreads of chapter 9's last section: I1 = 2.25 m1, I2 = m2."""
    return slider_crank_system(SliderCrankParameters(m1=m1, I1=2.25 * m1, m2=m2, I2=m2, m3=m3))


def _stability_function():
    """R(z) from one RK4 step of y' = mu y, confirmed against the library at a few points."""
    z, mu, step, y = sp.symbols("z mu Delta_t y")
    k1 = mu * y
    k2 = mu * (y + step / 2 * k1)
    k3 = mu * (y + step / 2 * k2)
    k4 = mu * (y + step * k3)
    factor = sp.expand(sp.simplify((y + step / 6 * (k1 + 2 * k2 + 2 * k3 + k4)) / y).subs(mu, z / step))
    points = np.array([-2.5, -1.0 + 2.0j, 2.8j])
    if not np.allclose(sp.lambdify(z, factor)(points), rk4_stability_function(points)):
        raise AssertionError("the sympy RK4 step does not match closedloop.fixed_step")
    return factor


def _without_fourth_order(expected):
    """A wrong R: the z^4 term left out (a scheme of order three)."""
    z = sp.Symbol("z")
    return sp.expand(expected - z**4 / 24)


def _critical_step():
    """The largest dt with growth per step <= 1 on the line alpha = beta = CRITICAL_GAIN."""
    return brentq(lambda dt: float(rk4_baumgarte_growth(CRITICAL_GAIN * dt, CRITICAL_GAIN * dt)) - 1.0,
                  1e-6, 1e-2, xtol=1e-15)


def _work():
    system = slider_crank_system()
    case = CASES[2]
    run = simulate(system, initial_state(system, case.phi0, case.dphi0), WORK_END, formulation=Baumgarte(5, 5),
                   method="DOP853", rtol=1e-10, atol=1e-10, t_eval=WORK_TIMES, work=True)
    return run.work[-1] - run.work[0]


def _scaled_condition():
    heavy_slider = _spread(1e-6, 1e-6, 1e6)
    return conditioning(heavy_slider, initial_state(heavy_slider, *TEST_STATE).s).equilibrated


def _heavy_crank_verdict():
    """'c' if the solves disagree; else 'a' or 'b' from m(phi) and the RK45 steps against Table 1."""
    heavy_crank, table = _spread(1e6, 1e-6, 1e-6), slider_crank_system()
    case = CASES[2]
    test = initial_state(heavy_crank, *TEST_STATE)
    solves = [f.accelerations(heavy_crank, 0.0, test.s, test.sd) for f in (Augmented(), Minimal())]
    if not np.allclose(solves[0], solves[1], rtol=1e-8, atol=0):
        return "c"
    m = [generalized_mass(heavy_crank, initial_state(heavy_crank, angle, 0.0).s)[0, 0]
         for angle in np.linspace(0.0, 2 * np.pi, 181)]
    steps = [simulate(mechanism, initial_state(mechanism, case.phi0, case.dphi0), 2.0, formulation=Baumgarte(5, 5),
                      method="RK45").n_steps for mechanism in (heavy_crank, table)]
    return "b" if max(m) / min(m) < 2 and steps[0] < 3 * steps[1] else "a"


CHECKS = {
    "9.4": Check("9.4", _stability_function, symbolic(),
                 "substitute each stage into the next, divide the new y by y, and replace mu by z / Delta_t; "
                 "the result is a polynomial in z alone.",
                 _without_fourth_order),
    "9.5": Check("9.5", _critical_step, numeric(1e-4, 0),
                 "with alpha = beta the two roots of (9.a) coincide and are real; where does RK4's "
                 "stability region meet the negative real axis?",
                 lambda expected: 0.5 * expected),
    # 1e-5: the trapezoidal rule is 1e-6 off; leaving out the torque's ripple is 2.6e-5 off
    "9.6": Check("9.6", _work, numeric(1e-5, 0),
                 "the power is M(t) phi' + F_x x_C' at each output time (mind force_sign, and that "
                 "gas_force takes x_C and x_C'); integrate it over the 5001 times from 0 to 5 s.",
                 lambda expected: -expected),
    "9.7": Check("9.7", _scaled_condition, numeric(1e-6, 0),
                 "scale rows and columns alike, D K D with D = diag(d); the constraint scales use the "
                 "columns of Phi_s already multiplied by the coordinate scales.",
                 lambda expected: 1e3 * expected),
    "9.8": Check("9.8", _heavy_crank_verdict, choice,
                 "compare the largest and smallest m(phi) of the heavy crank, and the two runs' n_steps.",
                 another_letter()),
}

check = make_check(CHECKS)
