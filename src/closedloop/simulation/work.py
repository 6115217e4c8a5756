"""The work W of the non-conservative forces, carried as the last entry of the integrator's state.

With ``simulate(work=True)`` every runner integrates ``[y, W]``, the formulation's state ``y``
with ``W' = tau(t, s, s') . s'`` appended, so that the energy balance
``Delta(T + Pi) = W`` can be checked along the run.  This module is the one place that
knows where W sits; a formulation that alters the integrator's steps (projection) carries
the entries after its own unchanged (rule 9 of :class:`~closedloop.formulations.Formulation`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["WORK_NAME", "with_work", "without_work", "work_of", "state_size"]

#: The name of the work's entry of the state, in error messages about tolerances.
WORK_NAME = "W"


def with_work(system, y0, rhs, unpack, mode, work_done):
    """A segment's start, right-hand side and unpacker with the work appended.

    Parameters
    ----------
    system : System
        The system; its ``applied_forces`` give tau of the power ``tau . s'``.
    y0 : ndarray
        The formulation's state at the segment's start.
    rhs, unpack : callable
        The formulation's right-hand side and unpacker on the branch ``mode``.
    mode : tuple of bool
        The branch of the switched force.
    work_done : float
        W at the segment's start [J].

    Returns
    -------
    y0, rhs, unpack
        The same three for the state ``[y, W]``.
    """
    def rhs_with_work(t, y):
        x = y[:-1]
        s, sd = unpack(x, t)
        power = system.applied_forces(t, s, sd, mode) @ sd
        return np.append(rhs(t, x), power)

    def unpack_with_work(y, t=None):
        return unpack(y[:-1], t)

    unpack_with_work.seed = unpack.seed
    return np.append(y0, work_done), rhs_with_work, unpack_with_work


def without_work(y, work):
    """The formulation's part of a state ``y`` (a vector, or states as columns), when ``work`` says W is in it."""
    return y[:-1] if work else y


def work_of(y):
    """W of a state (a float), or of states as columns (an array): the last entry."""
    return y[-1]


def state_size(formulation_size, work):
    """The length of the integrator's state: the formulation's, and one more with the work."""
    return formulation_size + (1 if work else 0)
