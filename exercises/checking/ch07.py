"""Checks for exercises/07-conclusions.md."""

import math

import numpy as np
import sympy as sp

from closedloop import Baumgarte, System, consistent_initial_state, simulate
from closedloop.four_bar import four_bar_model
from closedloop.slider_crank import (CASES, initial_state, slider_crank_model,
                                     slider_crank_system)

from . import Check, another_letter, as_numbers, choice, make_check, numeric, scaled, symbolic

#: The data of the four-bar exercises 7.7 to 7.9.
FOUR_BAR_DATA = {"l0": 4.0, "l1": 1.0, "l2": 3.5, "l3": 3.0, "m1": 1.0, "m2": 3.0, "m3": 2.5, "g": 9.81}
FOUR_BAR_START = dict(q0=[math.pi / 2], qd0=[2.0], z_guess=[0.5, 2.0])


def _run(system, phi0, dphi0, t_end, t_eval=None):
    """Chapter 6's setup: Baumgarte(5, 5), DOP853, rtol = atol = 1e-9."""
    return simulate(system, initial_state(system, phi0, dphi0), t_end, formulation=Baumgarte(5, 5),
                    method="DOP853", rtol=1e-9, atol=1e-9, t_eval=t_eval)


def _amplitude():
    """A(l1, a1, m1, l2, a2, m2, g) with Pi = A sin(phi) on the paper's branch, from the model's Pi."""
    model = slider_crank_model()
    phi, psi, _ = model.coordinates
    symbol = {str(p): p for p in model.parameters}
    on_branch = model.potential_energy.subs(sp.sin(psi), symbol["l1"] * sp.sin(phi) / symbol["l2"])  # (28)
    return sp.simplify(on_branch / sp.sin(phi))



def _amplitude_without_rod(expected):
    """A wrong amplitude: the rod's own weight about its end A left out (a2 = 0)."""
    return expected.subs(sp.Symbol("a2"), 0)


def _first_turn_time():
    """t1 with phi(t1) - phi0 = 2 pi in case 4, interpolated on a dense output grid."""
    case = CASES[4]
    result = _run(slider_crank_system(), case.phi0, case.dphi0, 20.0, np.linspace(0.0, 20.0, 20001))
    turned = result.coordinate("phi") - case.phi0
    end = np.argmax(turned >= 2 * math.pi)                     # first output after one full turn
    if not turned[end] >= 2 * math.pi:
        raise ValueError("case 4 does not complete a turn within 20 s")
    return np.interp(2 * math.pi, turned[end - 1:end + 1], result.t[end - 1:end + 1])


def _case_2_energy_change():
    system = slider_crank_system()
    case = CASES[2]
    result = _run(system, case.phi0, case.dphi0, 20.0)
    energy = system.energy(result.s, result.sd)
    return energy[-1] - energy[0]


def _four_bar():
    system = System(four_bar_model(), FOUR_BAR_DATA)
    return system, consistent_initial_state(system, **FOUR_BAR_START)


def _four_bar_energy():
    system, start = _four_bar()
    return system.energy(start.s, start.sd)


def _four_bar_crank_angle():
    system, start = _four_bar()
    result = simulate(system, start, 5.0, formulation=Baumgarte(5, 5), method="DOP853",
                      rtol=1e-10, atol=1e-10)
    return result.coordinate("theta1")[-1]


def _four_bar_residual():
    """The largest |f| of (32) over 10 s: Baumgarte(5, 5), DOP853, rtol = atol = 1e-9.

    Over a dense output grid (10 001 times): between the steps |f| is about ten times its value at
    the step ends (1.9e-9 m against 1.9e-10 m), so the step ends alone put the expected value a
    decade low, at the edge of the factor 10 that the check accepts for right answers.
    """
    system, start = _four_bar()
    result = simulate(system, start, 10.0, formulation=Baumgarte(5, 5), method="DOP853",
                      rtol=1e-9, atol=1e-9, t_eval=np.linspace(0.0, 10.0, 10_001))
    return result.max_constraint_error


def _same_decade(answer, expected):
    """Equal on a log scale, within a factor of 10."""
    answer = float(as_numbers(answer, expected))          # a finite number: not text such as "1e-8", nor True
    return answer > 0 and abs(math.log10(answer) - math.log10(expected)) < 1


def _gravity_over_a_turn():
    """'a' if Pi returns to its value after a full turn of the crank (no net work), else the sign's letter."""
    system = slider_crank_system()
    start, turned = (initial_state(system, angle, 0.0).s for angle in (0.3, 0.3 + 2 * math.pi))
    _, before = system.kinetic_and_potential_energy(start, np.zeros(3))
    _, after = system.kinetic_and_potential_energy(turned, np.zeros(3))
    work = before - after                                      # work of gravity = -(change of Pi)
    return "a" if math.isclose(work, 0.0, abs_tol=1e-9 * abs(before)) else ("b" if work > 0 else "c")


CHECKS = {
    "7.4": Check("7.4", _amplitude, symbolic(),
                 "replace sin(psi) with (28) on the branch, then divide by sin(phi); keep the symbols "
                 "l1, a1, m1, l2, a2, m2, g of slider_crank_model().parameters, not numbers.",
                 _amplitude_without_rod),
    "7.5": Check("7.5", _first_turn_time, numeric(1e-3, 0),
                 "the first full turn is the first time phi - phi0 reaches 2 pi; on a fine output grid, "
                 "interpolate t linearly between the two outputs that bracket it.", scaled()),
    "7.6": Check("7.6", _case_2_energy_change, numeric(1e-2, 0),
                 "T + Pi at t = 20 s minus T + Pi at t = 0, with system.energy, from a run with the "
                 "chapter's settings (DOP853 at 1e-9); a loss is negative.", scaled()),
    "7.7": Check("7.7", _four_bar_energy, numeric(1e-6, 0),
                 "each bar's T is (m/2)|v_centre|^2 + (m l^2/24) theta'^2; Pi is measured from the "
                 "pivots' height; start Newton from theta2 = 0.5, theta3 = 2.", scaled()),
    "7.8": Check("7.8", _four_bar_crank_angle, numeric(1e-3, 0),
                 "give theta1 as simulate returns it (unwrapped, not reduced to [0, 2 pi)), at t = 5 s "
                 "exactly, from a run with a tolerance of 1e-8 or tighter.", scaled()),
    "7.9": Check("7.9", _four_bar_residual, _same_decade,
                 "the result of simulate holds the residual of (32) at every output; take its largest "
                 "value over the whole 10 s run with Baumgarte(5, 5), DOP853 and rtol = atol = 1e-9.",
                 lambda expected: 1e3 * expected),
    "7.10": Check("7.10", _gravity_over_a_turn, choice,
                 "gravity's work is minus the change of Pi, and Pi depends on the configuration alone.",
                 another_letter()),
}

check = make_check(CHECKS)
