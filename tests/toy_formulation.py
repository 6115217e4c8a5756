"""A formulation defined outside the library, in this one file: the range-space (Schur complement) solve of (12).

Eliminating s'' from the augmented system (12) gives the multipliers from the r x r system

    (Phi_s M^-1 Phi_s^T) lambda = Phi_s M^-1 p1 - p2,      s'' = M^-1 (p1 - Phi_s^T lambda),

with ``p2 = -Phi_s' s'`` (11): the same accelerations as :class:`closedloop.Augmented`, by other
linear algebra.  It keeps the contract of :class:`closedloop.Formulation` with its defaults (state
``[s, s']``, every method), so it claims every runner: solve_ivp's methods, the compiled
"ode.dop853" and naive switching.  ``StepAltering`` alters the steps but forgets to refuse
"ode.dop853", which simulate must then refuse for it.
"""

from dataclasses import dataclass

import numpy as np

from closedloop import Formulation


@dataclass(frozen=True)
class RangeSpace(Formulation):
    """s'' of (12) through the Schur complement ``Phi_s M^-1 Phi_s^T`` (range-space method)."""

    name = "toy-range-space"

    def accelerations(self, system, t, s, sd, mode=None):
        M, p1, _, Phi, gamma = system.dynamics(t, s, sd, mode)
        M_inv_p1 = np.linalg.solve(M, p1)
        M_inv_PhiT = np.linalg.solve(M, Phi.T)
        multipliers = np.linalg.solve(Phi @ M_inv_PhiT, Phi @ M_inv_p1 + gamma)     # p2 = -gamma
        return M_inv_p1 - M_inv_PhiT @ multipliers


@dataclass(frozen=True)
class StepAltering(RangeSpace):
    """RangeSpace with an integrator of its own, which the compiled code cannot run: it must refuse it."""

    name = "toy-step-altering"

    def integrator(self, system, method):
        from scipy.integrate import RK45

        return RK45
