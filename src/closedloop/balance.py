"""The energy balance of a run: the change of T + Pi against the work of the applied forces.

Along an exact motion of (5)-(6), ``d(T + Pi)/dt = tau . s'``: the constraint
forces ``-Phi_s^T lambda`` do no work because ``Phi_s s' = f' = 0``.  So

    T(t) + Pi(t) - T(0) - Pi(0) = W(t) = integral_0^t tau . s' dt

holds for any consistent run.  A numerical run misses it by the integration
error, plus the work of the constraint forces on a drifting ``f' != 0``.

Here W comes from the run itself: ``simulate(..., work=True)`` integrates it as
one more state, by the same method and tolerances, so this works for any
:class:`~closedloop.model.System` and any applied force.  For the slider-crank,
:mod:`closedloop.studies.energy` computes the same two works after the run instead, in
closed form, independently of the integrator (chapter 11); chapter 9 uses this
module because its runs include formulations and systems that module does not cover.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError

__all__ = ["EnergyBalance", "energy_balance"]


@dataclass
class EnergyBalance:
    """The two sides of the energy balance along a run.

    Attributes
    ----------
    t : ndarray, shape (N,)
    energy_change : ndarray, shape (N,)
        ``T + Pi`` minus its value at the start [J].
    work : ndarray, shape (N,)
        W, the work of the non-conservative forces tau since the start [J].
    """

    t: np.ndarray
    energy_change: np.ndarray
    work: np.ndarray

    @property
    def residual(self) -> np.ndarray:
        """``Delta(T + Pi) - W`` [J]: zero for an exact motion."""
        return self.energy_change - self.work

    @property
    def max_residual(self) -> float:
        """The largest ``|Delta(T + Pi) - W|`` over the run [J]."""
        return float(np.max(np.abs(self.residual)))


def energy_balance(system, result):
    """The energy balance of a :class:`~closedloop.simulation.SimulationResult`.

    Parameters
    ----------
    system : System
        The system that was simulated.
    result : SimulationResult
        From ``simulate(..., work=True)``: the work W is integrated with the
        state, by the same integrator and tolerances.

    Returns
    -------
    EnergyBalance
    """
    if getattr(result, "work", None) is None:
        raise InputError("result: has no work; run simulate(..., work=True)")
    energy = system.energy(result.s, result.sd)
    return EnergyBalance(t=result.t, energy_change=energy - energy[0], work=result.work - result.work[0])
