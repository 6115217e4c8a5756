"""Checks for exercises/12-basins.md."""

import math

import numpy as np
import sympy as sp

from closedloop import Minimal, derive
from closedloop.studies.basin import reference_outcome
from closedloop.slider_crank import CASES, initial_state, slider_crank_model, slider_crank_system

from . import Check, another_letter, choice, make_check, numeric, scaled, symbolic

#: phi0 [rad] and phi0' [rad/s] of the state in exercise 12.6: the slider moving outward.
OUTWARD = (4.0, 1.0)


def _case_codes():
    """The four cases' outcome codes over 20 s, each from one adaptive run of simulate.

    ``reference_outcome`` (ClosedForm, ode.dop853, rtol 1e-10; a rotating run stops once it has turned)
    is the classification the chapter checks the batch integrator against, and costs about a sixth
    of a second batch run beside the student's (0.18 s against 1.2 s, measured here).
    """
    system = slider_crank_system()
    return np.array([reference_outcome(system, CASES[number].phi0, CASES[number].dphi0, 20.0)
                     for number in sorted(CASES)])


def _minimal_accelerations():
    system = slider_crank_system()
    state = initial_state(system, *OUTWARD)
    return Minimal().accelerations(system, 0.0, state.s, state.sd)


def _generalized_mass():
    """R^T M R at phi = psi = pi, from the derived model (R of (20) in sympy)."""
    model = slider_crank_model()
    phi, psi, _ = model.coordinates
    derived = derive(model)
    at = {phi: sp.pi, psi: sp.pi}
    Phi = derived.jacobian.subs(at)
    Phi_z, Phi_q = Phi[:, model.dependent_index.tolist()], Phi[:, model.independent_index.tolist()]
    R = sp.Matrix.vstack(sp.eye(1), -Phi_z.LUsolve(Phi_q))                           # (20), phi first
    return sp.simplify((R.T * derived.mass_matrix.subs(at) * R)[0, 0])


def _flip_coupling(expected):
    """m(pi) with the wrong sign of the crank-rod coupling term."""
    return expected.subs(sp.Symbol("a2"), -sp.Symbol("a2"))


def _speed_bound():
    """sqrt(2 (Pi(pi/2) - Pi(pi)) / m(pi)), with m(pi) from the sympy expression and Table 1."""
    system = slider_crank_system(torque=False)
    _, potential = system.kinetic_and_potential_energy(
        np.array([initial_state(system, angle, 0.0).s for angle in (math.pi / 2, math.pi)]).T, np.zeros((3, 2)))
    mass = float(_generalized_mass().subs(system.parameters.as_dict()))
    return math.sqrt(2.0 * (potential[0] - potential[1]) / mass)


def _gas_raises_the_bound():
    """'a', 'b' or 'c': the critical speed at phi0 = pi without torque, against the energy bound.

    Two speeds decide it: 'a' if the bound itself turns (the critical speed is not above it); else
    'c' if 1.01 times the bound turns (the critical speed lies within 1 % above the bound); else
    'b'.  (The exercise's grid, 2.5 % apart, cannot tell 'c' from 'b' by itself: a turn at its
    second speed places the critical speed anywhere up to 2.5 % above the bound.)  Each speed is
    classified by one adaptive run (``reference_outcome``, the chapter's reference).
    """
    bound = _speed_bound()
    system = slider_crank_system(torque=False)
    if reference_outcome(system, math.pi, bound, 20.0) == 1:
        return "a"                                           # turns at the bound: not above it
    return "c" if reference_outcome(system, math.pi, 1.01 * bound, 20.0) == 1 else "b"

CHECKS = {
    "12.5": Check("12.5", _case_codes, numeric(0, 0),
                  "pass the four angles as one array and the four speeds as another, in the order of the "
                  "cases; the result's codes hold one outcome per start.",
                  lambda expected: 1 - np.asarray(expected)),
    "12.6": Check("12.6", _minimal_accelerations, numeric(1e-8, 1e-10),
                  "c is zero in the row of phi and solves Phi_z c_z = -Phi_s' s' in the other rows; the right "
                  "side of (12.b) is R^T (p1 - M c), and s'' = R phi'' + c.", scaled()),
    "12.7": Check("12.7", _generalized_mass, symbolic(),
                  "at phi = psi = pi the derivative of (28) gives psi' in terms of phi', and the derivative of "
                  "(27) gives the slider's speed; put both into T and mind the sign of the coupling term.",
                  _flip_coupling),
    "12.8": Check("12.8", _speed_bound, numeric(1e-6, 0),
                  "set (1/2) m(pi) phi'^2 equal to the rise of Pi from phi = pi to phi = pi/2; take both from "
                  "the system without the torque (its masses and lengths are those of Table 1).", scaled()),
    "12.9": Check("12.9", _gas_raises_the_bound, choice,
                  "find the first of the 21 speeds whose code is 1 and compare it with the bound; which force "
                  "acts while the crank goes from pi to 2 pi?",
                  another_letter()),
}

check = make_check(CHECKS)
