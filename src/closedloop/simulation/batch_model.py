"""The minimal-coordinate ODE of a one-degree-of-freedom system on K states at once.

The batch integrator (:mod:`~closedloop.simulation.batch`) steps every cell in the
independent coordinate q of :class:`~closedloop.Minimal` (coordinate partitioning with
R of (20))::

    (R^T M R) q'' = R^T (p1 - M c),   c = [0; -Phi_z^{-1} Phi_s' s']

with arrays of shape (K,) in place of each number: the dependent coordinates z by a
vectorised Newton on f(q, z) = 0 (6), M, p1, Phi_s and Phi_s' s' from the model's array
functions (``System.dynamics_many``), the switched force's ``many``.  This module
evaluates that ODE and what the switching rule (:mod:`~closedloop.simulation.switching`)
asks of it: the rates of a switching function on either branch, and the probe of each
branch's motion where those rates vanish.
"""

from __future__ import annotations

import numpy as np

from ..errors import InputError
from ..formulations.minimal import minimal_accelerations
from ..kinematics import solve_dependent_many
from ..linalg import orthogonal_complement_many
from . import switching as rule

__all__ = ["BatchModel"]


class BatchModel:
    """The minimal-coordinate ODE of a one-degree-of-freedom :class:`~closedloop.model.System`, on arrays.

    Parameters
    ----------
    system : System
        One degree of freedom (``system.f == 1``); its switched force, if any, must
        give ``switching_functions_many`` and ``many``.

    Raises
    ------
    InputError
        For a system with more than one degree of freedom.
    """

    def __init__(self, system):
        if system.f != 1:
            raise InputError(f"system: the batch integrator needs one degree of freedom, got f = {system.f}")
        self.system = system
        self.q = int(system.q_index[0])
        self.z = system.z_index
        self.force = system.force
        self.switches = len(self.force.switch_names) if self.force is not None else 0
        self.evaluations = 0           # vectorised acceleration evaluations
        self.cell_evaluations = 0      # the same, counted per cell

    def configuration(self, q, z_guess):
        """s and Phi_s with s[q] = q and z from Newton on f(q, z) = 0 (6), started at z_guess."""
        return solve_dependent_many(self.system, q, z_guess)

    def evaluate(self, t, q, qd, z_guess, mode):
        """The state and its accelerations at K cells, each on its branch ``mode[:, j]``.

        Returns
        -------
        dict
            s, sd, sdd, R and c of shape (n, K), and qdd of shape (K,).
        """
        s, Phi = self.configuration(q, z_guess)
        point = self._accelerations(t, s, Phi, qd, mode)
        point["s"] = s
        return point

    def _accelerations(self, t, s, Phi, qd, mode, sd=None):
        system = self.system
        size = s.shape[1]
        R = orthogonal_complement_many(Phi, system.q_index, self.z)      # (20), shape (n, 1, K)
        if sd is None:
            sd = R[:, 0] * qd
        M, p1, _, _, gamma = system.dynamics_many(t, s, sd)
        if self.force is not None:
            p1 = p1 + self.force.many(t, s, sd, mode)
        qdd, c = minimal_accelerations(M, p1, Phi, gamma, R, self.z)
        qdd, R = qdd[0], R[:, 0]
        self.evaluations += 1
        self.cell_evaluations += size
        return {"sd": sd, "sdd": R * qdd + c, "qdd": qdd, "R": R, "c": c}

    def accelerations(self, t, s, sd, mode):
        """s'' of (12) at K states ``(s, s')`` given in all coordinates, on branches ``mode``."""
        Phi = self.system.constraints_and_jacobian_many(s)[1]
        return self._accelerations(t, s, Phi, sd[self.q], mode, sd=sd)["sdd"]

    def rest_accelerations(self, t, s, mode):
        """s'' at rest (s' = 0) on branch ``mode``."""
        Phi = self.system.constraints_and_jacobian_many(s)[1]
        return self._accelerations(t, s, Phi, np.zeros(s.shape[1]), mode)["sdd"]

    def switching(self, t, s, sd):
        """The switching functions h at K states, shape (k, K)."""
        return self.force.switching_functions_many(t, s, sd)

    def rates(self, t, s, sd, sdd):
        """dh/dt of every switching function along the motion (the rule's :func:`switching_rate`)."""
        return rule.switching_rate(self.switching, t, s, sd, sdd)

    def side_rates(self, t, s, sd, q, qd, z, mode, i):
        """Rates of switch i on its "off" and "on" branches at the given states (one switch for all)."""
        size = q.size
        trial = np.concatenate((mode, mode), axis=1)          # both branches in one evaluation
        trial[i, :size], trial[i, size:] = False, True
        t2 = np.concatenate((np.broadcast_to(t, (size,)),) * 2)
        point = self.evaluate(t2, np.tile(q, 2), np.tile(qd, 2), np.tile(z, 2), trial)
        rates = self.rates(t2, np.tile(s, 2), point["sd"], point["sdd"])[i]
        return rates[:size], rates[size:]

    def probe_rates(self, t, s, sd, mode, i):
        """The rule's :func:`~closedloop.simulation.switching.probe_rates` of switch i at K states."""
        def accelerations(side):
            trial = mode.copy()
            trial[i] = side
            return lambda time, q, qd: self.accelerations(time, q, qd, trial)

        return rule.probe_rates(self.switching, accelerations, t, s, sd, i)
