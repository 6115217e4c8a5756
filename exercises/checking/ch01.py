"""Checks for exercises/01-closed-loop-systems.md."""

import math

import numpy as np

from closedloop import consistent_initial_state
from closedloop.slider_crank import slider_crank_model, slider_crank_system

from . import Check, _numbers, another_letter, choice, make_check, numeric, scaled


def _degrees_of_freedom():
    model = slider_crank_model()
    return len(model.coordinates) - len(model.constraints)


def _dead_centre():
    state = consistent_initial_state(slider_crank_system(), [math.pi], [0.0], [3.0, 1.0])
    return state.s[1:]


def same_configuration(rtol=1e-9, atol=1e-12):
    """Compare [psi, x_C] pairs with psi taken modulo 2 pi: compare [cos psi, sin psi, x_C].

    The answer is first taken as every numeric answer is (:func:`_numbers`: two finite numbers), so that
    ``[True, True]`` is the wrong kind of answer, not the pair (1 rad, 1 m).
    """
    compare = numeric(rtol, atol)

    def configuration(pair):
        psi, x_C = pair
        return [math.cos(psi), math.sin(psi), x_C]
    return lambda answer, expected: compare(configuration(_numbers(answer, expected)),
                                            configuration(np.asarray(expected, dtype=float)))


def _left_branch_x():
    return consistent_initial_state(slider_crank_system(), [1.0], [0.0], [0.6, -2.0]).s[2]


def _stroke():
    system = slider_crank_system()
    outer = consistent_initial_state(system, [0.0], [0.0], [3.0, 5.0]).s[2]          # phi = 0
    inner = consistent_initial_state(system, [math.pi], [0.0], [3.0, 1.0]).s[2]      # phi = pi
    return outer - inner


def _can_switch_branches():
    """The branches psi and pi - psi meet only if l1 |sin phi| = l2 is possible: "b" (yes) if l1 >= l2."""
    p = slider_crank_system().parameters
    return "a" if p.l1 < p.l2 else "b"


CHECKS = {
    "1.4": Check("1.4", _degrees_of_freedom, numeric(0, 0), "count coordinates minus independent constraints.",
                 lambda expected: expected + 1),
    "1.5": Check("1.5", _dead_centre, same_configuration(),
                 "at phi = pi, (28) gives sin psi = 0; then use (27) with x_C > 0 (the slider right of "
                 "the crank).",
                 scaled()),
    "1.6": Check("1.6", _left_branch_x, numeric(1e-9, 1e-12),
                 "start Newton with psi near 0: the rod then points the other way.", scaled()),
    "1.7": Check("1.7", _stroke, numeric(1e-12, 1e-12),
                 "the slider's extreme positions are the two dead centres, phi = 0 and phi = pi.", scaled()),
    "1.8": Check("1.8", _can_switch_branches, choice,
                 "how many solutions does sin psi = (l1/l2) sin phi have when l1 < l2, and do they ever meet?",
                 another_letter()),
}

check = make_check(CHECKS)
