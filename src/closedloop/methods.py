"""The names of the integration methods, written once.

Every list of methods in the library (what :func:`closedloop.simulate` accepts,
what the projection can reset, what the baseline and the benchmark run, the
command line's help) is taken from here.  The module imports nothing from
closedloop, so any module may use it without an import cycle.
"""

from __future__ import annotations

from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, Radau

__all__ = ["SOLVE_IVP_METHODS", "COMPILED_METHOD", "SOLVER_METHODS", "SOLVER_CLASSES",
           "EXPLICIT_RUNGE_KUTTA_METHODS", "IMPLICIT_METHODS"]

#: The methods of ``scipy.integrate.solve_ivp``, by name and in the order the book lists them.
SOLVER_CLASSES = {"RK45": RK45, "RK23": RK23, "DOP853": DOP853, "Radau": Radau, "BDF": BDF, "LSODA": LSODA}
SOLVE_IVP_METHODS = tuple(SOLVER_CLASSES)
#: The compiled DOP853 of ``scipy.integrate.ode`` (:mod:`closedloop.simulation.dop853`).
COMPILED_METHOD = "ode.dop853"
#: Every method :func:`closedloop.simulate` accepts by name.
SOLVER_METHODS = SOLVE_IVP_METHODS + (COMPILED_METHOD,)
#: The explicit Runge-Kutta methods of solve_ivp: their whole memory is the current state and
#: its derivative, so the state can be reset after a step (:class:`closedloop.Projected`).
EXPLICIT_RUNGE_KUTTA_METHODS = ("RK23", "RK45", "DOP853")
#: The implicit methods of solve_ivp (for stiff problems).
IMPLICIT_METHODS = ("Radau", "BDF", "LSODA")
