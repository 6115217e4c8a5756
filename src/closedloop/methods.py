"""The names of the integration methods, written once.

Every list of methods in the library (what :func:`closedloop.simulate` accepts,
what the projection can reset, what the baseline and the benchmark run, the
command line's help) is taken from here.  The module imports nothing from
closedloop but :mod:`closedloop.loading` (which imports nothing from closedloop),
so any module may use it without an import cycle.

Nor does it import scipy.integrate (whose package imports scipy.optimize, scipy.sparse,
scipy.linalg and scipy.special, about 0.3 s) until a solver class is asked for:
:data:`SOLVER_CLASSES` is made on first use (a module ``__getattr__``, PEP 562), so that a run
with the compiled DOP853 (:mod:`closedloop.simulation.dop853_code`) never imports it.
"""

from __future__ import annotations

from .loading import first_use

__all__ = ["SOLVE_IVP_METHODS", "COMPILED_METHOD", "SOLVER_METHODS", "SOLVER_CLASSES",
           "EXPLICIT_RUNGE_KUTTA_METHODS", "IMPLICIT_METHODS", "solver_classes", "solver_class", "scipy_integrate"]

#: The methods of ``scipy.integrate.solve_ivp``, by name and in the order the book lists them.
SOLVE_IVP_METHODS = ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA")
#: The compiled DOP853 of ``scipy.integrate.ode`` (:mod:`closedloop.simulation.dop853`).
COMPILED_METHOD = "ode.dop853"
#: Every method :func:`closedloop.simulate` accepts by name.
SOLVER_METHODS = SOLVE_IVP_METHODS + (COMPILED_METHOD,)
#: The explicit Runge-Kutta methods of solve_ivp: their whole memory is the current state and
#: its derivative, so the state can be reset after a step (:class:`closedloop.Projected`).
EXPLICIT_RUNGE_KUTTA_METHODS = ("RK23", "RK45", "DOP853")
#: The implicit methods of solve_ivp (for stiff problems).
IMPLICIT_METHODS = ("Radau", "BDF", "LSODA")


def solver_classes():
    """``{name: class}`` of the :data:`SOLVE_IVP_METHODS` (scipy.integrate's OdeSolver subclasses).

    Imports scipy.integrate at the first call; every call returns the same dict, ``SOLVER_CLASSES``.
    """
    classes = globals().get("SOLVER_CLASSES")
    if classes is None:
        integrate = scipy_integrate()
        classes = globals()["SOLVER_CLASSES"] = {name: getattr(integrate, name) for name in SOLVE_IVP_METHODS}
    return classes


def solver_class(method):
    """The OdeSolver class of ``method``: a name of :data:`SOLVE_IVP_METHODS`, or a class, given back."""
    return solver_classes()[method] if isinstance(method, str) else method


@first_use
def scipy_integrate():
    """scipy.integrate, imported at the first call (its import time is left out of a run's cpu_time)."""
    import scipy.integrate

    return scipy.integrate


def __getattr__(name):
    """``SOLVER_CLASSES``, made on first use: the methods of ``scipy.integrate.solve_ivp`` by name."""
    if name == "SOLVER_CLASSES":
        return solver_classes()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | {"SOLVER_CLASSES"})
