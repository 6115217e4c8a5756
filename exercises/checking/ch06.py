"""Checks for exercises/06-four-cases.md."""

import math

import numpy as np

from closedloop import Baumgarte, Minimal, simulate
from closedloop.slider_crank import CASES, READINGS, classify_motion, initial_state, slider_crank_system
from closedloop.studies.readings import reading_outcomes

from . import Check, another_letter, choice, make_check, numeric, scaled


def _run(system, phi0, dphi0, t_end=20.0, formulation=None):
    """The chapter's setup: Baumgarte(5, 5) unless told otherwise, DOP853, rtol = atol = 1e-9."""
    formulation = Baumgarte(5, 5) if formulation is None else formulation
    return simulate(system, initial_state(system, phi0, dphi0), t_end, formulation=formulation,
                    method="DOP853", rtol=1e-9, atol=1e-9)


def _new_start():
    return classify_motion(_run(slider_crank_system(), math.pi, 1.2))


def _case_3_excursion():
    case = CASES[3]
    result = _run(slider_crank_system(), case.phi0, case.dphi0)
    return np.max(np.abs(result.coordinate("phi") - case.phi0))


def _case_3_sticks_at():
    case = CASES[3]
    result = _run(slider_crank_system(), case.phi0, case.dphi0, 40.0, Minimal())
    return result.sticking_intervals[0][0]


def _matching_readings():
    """The readings whose four cases all move as the paper finds (the study's runs, case by case).

    A reading's cases are run in order and it is given up at its first case that disagrees, so
    only the agreeing reading runs all four: the count of ``reading_outcomes()`` in about half its
    runs.
    """
    def agrees(name, number):
        return reading_outcomes(readings=[name], cases=[number])[0].motion == CASES[number].finding

    return sum(all(agrees(name, number) for number in CASES) for name in READINGS)


def _without_gas():
    """'b' if case 3 rotates without the gas force, 'c' if it swings undamped, 'a' if its swing decays."""
    case = CASES[3]
    result = _run(slider_crank_system(gas=False), case.phi0, case.dphi0)
    if classify_motion(result) == "full rotation":
        return "b"
    phi, third = result.coordinate("phi"), result.t[-1] / 3
    first, last = phi[result.t <= third].max(), phi[result.t >= 2 * third].max()
    return "c" if math.isclose(first, last, rel_tol=1e-3) else "a"


CHECKS = {
    "6.4": Check("6.4", _new_start, choice,
                 "simulate 20 s and ask classify_motion; compare the start with cases 1 and 4.",
                 lambda expected: "full rotation" if expected == "oscillation" else "oscillation"),
    "6.5": Check("6.5", _case_3_excursion, numeric(1e-3, 1e-6),
                 "take the largest |phi - phi0| over the whole run, in radians, from the unwrapped phi "
                 "that simulate returns.", scaled()),
    "6.6": Check("6.6", _case_3_sticks_at, numeric(0, 0.05),
                 "run 40 s with formulation=Minimal(); the result's sticking_intervals holds (start, end) "
                 "pairs.", scaled()),
    "6.7": Check("6.7", _matching_readings, numeric(0, 0),
                 "a reading counts only if all four of its cases agree with CASES[n].finding.",
                 lambda expected: expected + 1),
    "6.8": Check("6.8", _without_gas, choice,
                 "with gas=False only gravity and the drive torque act; compare the largest phi of the "
                 "first and the last swings.", another_letter()),
}

check = make_check(CHECKS)
