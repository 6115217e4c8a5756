"""Hairer and Wanner's compiled DOP853 and its coefficients, through scipy's public interface.

``scipy.integrate.ode(f).set_integrator("dop853")`` runs Hairer and Wanner's DOP853 code
[Hairer, Nørsett, Wanner, *Solving ODEs I*, section II.10] with a compiled step loop, and
the class ``scipy.integrate.DOP853`` carries the coefficients of the same pair and of its
continuous extension as class attributes.  Both come from ``scipy.integrate``, imported on
first use (:func:`closedloop.methods.scipy_integrate`: its import time is left out of a
run's cpu_time), so that ``import closedloop`` imports no scipy subpackage.

:func:`dopri853` always gives the code a ``solout``: scipy's C translation of the code
(``dop.c``, ``dp86co``) leaves its flag ``irtrn`` uninitialised when it has none, and then
evaluates f at the start of a step again whenever that garbage is 2 or more, which makes the
count of evaluations depend on what ran before.
"""

from __future__ import annotations

import warnings
from types import SimpleNamespace

import numpy as np

from ..loading import first_use
from ..methods import scipy_integrate

__all__ = ["coefficients", "dopri853", "SAFETY", "IFACTOR", "DFACTOR", "BETA", "VERBOSITY"]

#: scipy's defaults of ``ode(...).set_integrator("dop853")``.
SAFETY, IFACTOR, DFACTOR, BETA = 0.9, 6.0, 0.3, 0.0
#: ``verbosity`` of the code: negative, no messages printed.
VERBOSITY = -1


@first_use
def coefficients():
    """DOP853's coefficients, as ``scipy.integrate.DOP853`` carries them.

    Returns
    -------
    types.SimpleNamespace
        ``stages`` (12), the step's ``A`` (12 x 12), ``B`` and ``C`` (12), and the
        continuous extension's ``A_EXTRA`` (3 x 16), ``C_EXTRA`` (3) and ``D`` (4 x 16).
    """
    solver = scipy_integrate().DOP853
    return SimpleNamespace(stages=solver.n_stages, A=solver.A, B=solver.B, C=solver.C, A_EXTRA=solver.A_EXTRA,
                           C_EXTRA=solver.C_EXTRA, D=solver.D)


def _no_solout(t, y):
    """The ``solout`` of a call without one: go on (0), and the code's flag ``irtrn`` is set."""
    return 0


def dopri853(f, t0, y0, t_end, *, rtol, atol, nsteps, first_step=0.0, max_step=0.0, solout=None,
             dfactor=DFACTOR, beta=BETA):
    """Integrate ``y' = f(t, y)`` from ``t0`` to ``t_end`` with the compiled DOP853: ``(t, y, code)``.

    ``solver = ode(f).set_integrator("dop853", ...)``, ``solver.set_solout(solout)``,
    ``solver.set_initial_value(y0, t0)``, ``solver.integrate(t_end)``, with ``solver.t``,
    ``solver.y`` and ``solver.get_return_code()`` returned; a failure (a negative code) is
    returned, not also announced by a warning.

    Parameters
    ----------
    f : callable
        ``f(t, y) -> sequence`` of length ``y0.size``.
    t0, t_end : float
    y0 : array_like, shape (n,)
        Not changed (the code works on a copy).
    rtol, atol : float
    nsteps : int
        Steps allowed.
    first_step, max_step : float, optional
        0 lets the code choose.
    solout : callable, optional
        ``solout(t, y) -> int`` after every accepted step (and once at ``t0``); -1 stops the
        code.  Without one the code gets one that returns 0.
    dfactor : float, optional
        The code's ``fac1`` (scipy's ``dfactor``), the smallest ratio of a new step to the
        last; in scipy's C translation also the ratio of every retry to a rejected step
        (see :data:`closedloop.simulation.dop853.REJECTION_FACTOR`).
    beta : float, optional
        The weight of the last accepted step's error in the choice of the next step
        (stabilised step size control, Hairer's ``WORK(5)``); scipy's default 0 leaves it out.

    Returns
    -------
    t : float
        Where the code stopped (``t_end``, or the end of the step where ``solout`` stopped it).
    y : ndarray, shape (n,)
    code : int
        1 done, 2 stopped by ``solout``; -1 inconsistent input, -2 more than ``nsteps``
        steps needed, -3 step size too small, -4 probably stiff.
    """
    solver = scipy_integrate().ode(f).set_integrator(
        "dop853", rtol=rtol, atol=atol, nsteps=nsteps, max_step=max_step, first_step=first_step, safety=SAFETY,
        ifactor=IFACTOR, dfactor=dfactor, beta=beta, verbosity=VERBOSITY)
    solver.set_solout(solout or _no_solout)
    solver.set_initial_value(np.array(y0, dtype=float), t0)       # a copy: the code changes y in place
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)              # the code's failure, returned as its code
        y = solver.integrate(t_end)
    return solver.t, y, solver.get_return_code()
