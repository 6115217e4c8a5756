"""The formulation contract: what :func:`closedloop.simulate` may ask of a formulation.

A formulation turns Lagrange's equations with multipliers (5)-(12) of one
:class:`~closedloop.model.System` into a first-order ODE ``y' = F(t, y)`` that
an integrator can step.  Every formulation is a small immutable object, a
subclass of :class:`Formulation`, and keeps the rules written in that class's
docstring.  The runners of :mod:`closedloop.simulation` rely on those rules
alone: they never test which formulation they were given.
"""

from __future__ import annotations

import numpy as np

__all__ = ["Formulation", "StateUnpacker"]


class StateUnpacker:
    """``y -> (s, s')`` for the state vector ``y`` of a redundant-coordinate formulation.

    The state is ``y = [s, s']``: no work, no memory.  Formulations whose state
    is shorter (minimal coordinates) return their own unpacker with the same
    two methods.
    """

    def __init__(self, n):
        self.n = n

    def __call__(self, y, t=None):
        """``(s, s')`` from ``y``; ``t`` is only for error messages."""
        return y[:self.n], y[self.n:]

    def seed(self, s_start):
        """Start of a segment at coordinates ``s_start`` (nothing to remember here)."""

    def many(self, states, times):
        """``(s, s')`` as n x K arrays for K states given as the columns of ``states``."""
        return states[:self.n], states[self.n:]


class Formulation:
    """Base class of the formulations; its docstring is their contract.

    A formulation keeps these rules, so that :func:`closedloop.simulate`, its
    runners and the studies can use any of them without knowing which it is:

    1. ``name`` is a class attribute, the formulation's one spelling: the
       registry of :mod:`closedloop.formulations`, the command line and
       ``SimulationResult.formulation`` use it, and
       ``formulation_from_name(result.formulation)`` gives back its kind, with
       default parameters: the result records the name only, not the gains or
       a NullSpace basis.
    2. ``pack(system, s, sd) -> y`` builds the integrator's state vector from
       consistent coordinates and velocities; ``state_names(system)`` names the
       entries of ``y`` (for error messages).
    3. ``unpacker(system) -> unpack`` returns a new object, one per integration
       segment, with ``unpack(y, t=None) -> (s, s')`` and ``unpack.seed(s0)``,
       called once at the segment's start, and ``unpack.many(Y, times)`` for K
       states as columns at once (n x K arrays).  An unpacker may keep state within
       its segment (minimal coordinates warm-start Newton), never across
       segments or runs.
    4. ``make_rhs(system, mode, unpack) -> rhs`` returns ``rhs(t, y)``, the
       right-hand side on the smooth branch ``mode`` of the system's switched
       force (a tuple of bool, one per switch).  It returns a sequence of
       ``len(y)`` floats, and raises
       :class:`~closedloop.errors.SingularConfigurationError` (naming the time)
       where its own matrices are singular; it never returns NaN for that.
    5. ``accelerations(system, t, s, sd, mode=None) -> s''`` gives the
       accelerations of this formulation at a consistent state (for the
       multipliers, the switch decisions and the tests).
    6. ``switch_accelerations(system, mode)`` returns a faster
       ``(t, s, sd) -> s''`` of (12) without stabilisation, used to decide the
       branch at a switch, or None: the runner then solves (12).
    7. ``check_method(method)`` raises :class:`~closedloop.errors.InputError`
       before any integration for a method this formulation cannot run;
       ``integrator(system, method)`` returns the solve_ivp method to run
       (the method itself, unless the formulation alters the steps).
    8. Capability flags, read by the runners instead of type tests:
       ``guards_branch``: the formulation itself stops where it would leave
       its assembly branch (minimal coordinates), so the runner adds no branch
       guard but watches its turning points at dead positions
       (:mod:`closedloop.simulation.watch`); ``guards_partition``: it uses
       the model's partition (R of (20), Phi_z) and stops by itself where
       det Phi_z = 0 (it divides by it, or checks it), so an integration that
       can not go on names a nearly singular Phi_z as the cause; ``gains``:
       the Baumgarte gains ``(alpha, beta)``, or None.

    A new formulation subclasses this class (or one of its subclasses) in one
    module of this package and adds itself to the registry in ``__init__``.
    """

    name = ""
    guards_branch = False
    guards_partition = False

    @property
    def gains(self):
        """``(alpha, beta)`` of Baumgarte's stabilisation (15), or None when there are none."""
        return None

    def pack(self, system, s, sd):
        return np.concatenate((s, sd))

    def state_names(self, system):
        names = list(system.coordinate_names)
        return names + [f"d{name}/dt" for name in names]

    def unpacker(self, system):
        return StateUnpacker(system.n)

    def make_rhs(self, system, mode, unpack):
        n = system.n
        accelerations = self.accelerations

        def rhs(t, y):
            s, sd = y[:n], y[n:]
            return np.concatenate((sd, accelerations(system, t, s, sd, mode)))

        return rhs

    def accelerations(self, system, t, s, sd, mode=None):      # pragma: no cover - every subclass has one
        raise NotImplementedError

    def switch_accelerations(self, system, mode):
        return None

    def check_method(self, method):
        """Every method is allowed unless a subclass says otherwise."""

    def integrator(self, system, method):
        return method
