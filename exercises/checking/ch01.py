"""Checks for exercises/01-closed-loop-systems.md."""

import math

from closedloop import consistent_initial_state
from closedloop.slider_crank import slider_crank_model, slider_crank_system

from . import Check, choice, make_check, numeric, scaled


def _degrees_of_freedom():
    model = slider_crank_model()
    return len(model.coordinates) - len(model.constraints)


def _dead_centre():
    state = consistent_initial_state(slider_crank_system(), [math.pi], [0.0], [3.0, 1.0])
    return state.s[1:]


def _left_branch_x():
    return consistent_initial_state(slider_crank_system(), [1.0], [0.0], [0.6, -2.0]).s[2]


def _stroke():
    p = slider_crank_system().parameters
    return (p.l1 + p.l2) - (p.l2 - p.l1)


CHECKS = {
    "1.1": Check("1.1", _degrees_of_freedom, numeric(0, 0), "count coordinates minus independent constraints.",
                 lambda expected: expected + 1),
    "1.2": Check("1.2", _dead_centre, numeric(1e-9, 1e-12),
                 "at phi = pi, (28) forces sin psi = 0; which root keeps the slider right of the crank?",
                 scaled()),
    "1.3": Check("1.3", _left_branch_x, numeric(1e-9, 1e-12),
                 "start Newton with psi near 0: the rod then points the other way.", scaled()),
    "1.4": Check("1.4", _stroke, numeric(1e-12, 1e-12),
                 "the slider's extreme positions are the two dead centres, phi = 0 and phi = pi.", scaled()),
    "1.5": Check("1.5", lambda: "b", choice,
                 "how many solutions does sin psi = (l1/l2) sin phi have when l1 < l2, and do they ever meet?",
                 lambda expected: "a"),
}

check = make_check(CHECKS)
