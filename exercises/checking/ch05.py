"""Checks for exercises/05-slider-crank-model.md."""

import functools
import math

import numpy as np
import sympy as sp
from scipy.integrate import quad

from closedloop.slider_crank import (
    CASES,
    READINGS,
    gas_force,
    initial_state,
    slider_crank_model,
    slider_crank_system,
)
from closedloop.studies.readings import reading_outcomes

from . import Check, choice, make_check, numeric, scaled, symbolic

#: The time [s] and the crank's state (phi, phi') of exercise 5.6.
FORCE_TIME, FORCE_ANGLE, FORCE_SPEED = 0.25, 5.0, 1.0



def _without_rod_spin(expected):
    """A plausible wrong T: the rod's rotation about its centre of mass forgotten."""
    I2, dpsi = sp.symbols("I2 dpsi")
    return expected - I2 * dpsi**2 / 2


def _potential_at_quarter_turn():
    system = slider_crank_system()
    state = initial_state(system, math.pi / 2, 0.0)
    return system.kinetic_and_potential_energy(state.s, state.sd)[1]


def _applied_forces():
    """Q* of the drive torque and the gas force: p1 with them minus p1 without them."""
    state = initial_state(slider_crank_system(), FORCE_ANGLE, FORCE_SPEED)
    with_forces = slider_crank_system().dynamics(FORCE_TIME, state.s, state.sd)[1]
    without = slider_crank_system(torque=False, gas=False).dynamics(FORCE_TIME, state.s, state.sd)[1]
    return with_forces - without


@functools.lru_cache(maxsize=None)
def _reproducing_reading():
    """The one reading whose cases 1 and 2 move as the paper finds, the slider never stuck, no run-away.

    A reading's case 2 is run only if its case 1 passed (the study's runs, case by case).
    """
    def passes(name, number):
        o = reading_outcomes(readings=[name], cases=[number])[0]
        return o.motion == CASES[number].finding and o.stuck_at is None and o.runaway_at is None

    matching = [name for name in READINGS if all(passes(name, number) for number in (1, 2))]
    if len(matching) != 1:
        raise ValueError(f"expected one reproducing reading, found {matching}")
    return matching[0]


def _gas_work_last_half_metre():
    sign = READINGS[_reproducing_reading()].force_sign
    return sign * quad(lambda x: gas_force(x, 1.0), 5.0, 5.5)[0]


def _initial_velocities():
    return initial_state(slider_crank_system(), math.pi / 2, 1.0).sd[1:]


CHECKS = {
    "5.4": Check("5.4", lambda: slider_crank_model().kinetic_energy, symbolic(),
                 "each body contributes m v_C^2 / 2 of its centre of mass plus I omega^2 / 2 about that centre; "
                 "the rod's centre is a2 from the crank pin A, towards the slider.",
                 _without_rod_spin),
    "5.5": Check("5.5", _potential_at_quarter_turn, numeric(1e-6, 1e-9),
                 "Pi is the sum of m g y over the centres of mass; at phi = pi/2, (28) gives sin psi.",
                 scaled()),
    "5.6": Check("5.6", _applied_forces, numeric(1e-6, 1e-9),
                 "read Q_k off the virtual work as the coefficient of delta q_k; in the reproducing reading "
                 "the gas force must take energy out while the slider moves outward.",
                 lambda expected: np.asarray(expected) * np.array([1.0, 1.0, -1.0])),
    "5.7": Check("5.7", _gas_work_last_half_metre, numeric(1e-6, 1e-9),
                 "work is the integral of the generalised force on x_C, as it enters (31) in the reproducing "
                 "reading, over the displacement from 5 m to 5.5 m; integrate the constant and the periodic "
                 "part of (5.e) separately.",
                 scaled()),
    "5.8": Check("5.8", _initial_velocities, numeric(1e-6, 1e-9),
                 "differentiate (27)-(28) in time and put phi = pi/2, sin psi = l1/l2 in the result.",
                 scaled()),
    "5.9": Check("5.9", _reproducing_reading, choice,
                 "which reading lets case 1 swing and case 2 turn full circle, with the slider never stuck?",
                 lambda expected: next(name for name in READINGS if name != expected)),
}

check = make_check(CHECKS)
