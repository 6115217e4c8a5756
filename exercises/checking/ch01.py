"""Checks for exercises/01-closed-loop-systems.md."""

import math

from closedloop import consistent_initial_state
from closedloop.slider_crank import slider_crank_model, slider_crank_system

from . import Check, another_letter, choice, make_check, numeric, same_angles, scaled


def _degrees_of_freedom():
    model = slider_crank_model()
    return len(model.coordinates) - len(model.constraints)


def _dead_centre():
    state = consistent_initial_state(slider_crank_system(), [math.pi], [0.0], [3.0, 1.0])
    return state.s[1:]


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
    "1.5": Check("1.5", _dead_centre, same_angles(angles=[0]),
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
