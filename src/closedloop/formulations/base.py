"""The formulation contract: what :func:`closedloop.simulate` may ask of a formulation.

A formulation turns Lagrange's equations with multipliers (5)-(12) of one
:class:`~closedloop.model.System` into a first-order ODE ``y' = F(t, y)`` that
an integrator can step.  Every formulation is a small immutable object, a
subclass of the abstract :class:`Formulation`, and keeps the rules written in
that class's docstring.  The runners of :mod:`closedloop.simulation` rely on
those rules alone: they never test which formulation they were given.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

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


class Formulation(ABC):
    """Abstract base class of the formulations; its docstring is their contract.

    A formulation keeps these rules, so that :func:`closedloop.simulate`, its
    runners and the studies can use any of them without knowing which it is.
    A subclass must give ``name`` and :meth:`accelerations`; every other
    method has a default for a state ``y = [s, s']``.

    1. ``name`` is a class attribute, the formulation's one spelling: the
       registry of :mod:`closedloop.formulations`, the command line and
       ``SimulationResult.formulation`` use it, and
       ``formulation_from_name(result.formulation)`` gives back its kind, with
       default parameters (the result records the name only).  The class can
       be made with no arguments.  No other module types the name.
    2. ``pack(system, s, sd) -> y`` builds the integrator's state vector from
       consistent coordinates and velocities; ``state_names(system)`` names the
       entries of ``y`` (for error messages about tolerances).
    3. ``unpacker(system) -> unpack`` returns a new object, one per integration
       segment, with ``unpack(y, t=None) -> (s, s')``, ``unpack.seed(s0)``,
       called once at the segment's start, and ``unpack.many(Y, times)`` for K
       states as columns (n x K arrays), in order along the path.  Runners
       reach s and s' only through it, never by slicing ``y``: the
       solve_ivp runner at every event and step end, the compiled runner
       ("ode.dop853") after every accepted step (for the switching functions)
       and, with a second, fresh unpacker seeded at the segment's start, for
       the segment's outputs.  An unpacker may keep state within its segment
       (minimal coordinates warm-start Newton), never across segments or runs.
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
       ``integrator(system, method)`` returns what solve_ivp runs (the method
       itself, unless the formulation alters the steps).  The compiled
       "ode.dop853" steps in compiled code that no formulation can alter: a
       formulation whose ``integrator`` does not give that method back
       unchanged must refuse it in ``check_method``, and ``simulate`` refuses
       it before integrating if it does not.
    8. Capability flags, read by the runners instead of type tests:
       ``guards_branch``: the formulation itself stops where it would leave
       its assembly branch (minimal coordinates), so the runner adds no branch
       guard but watches its turning points at dead positions
       (:mod:`closedloop.simulation.watch`); ``guards_partition``: it uses
       the model's partition (R of (20), Phi_z) and stops by itself where
       det Phi_z = 0 (it divides by it, or checks it), so an integration that
       can not go on names a nearly singular Phi_z as the cause; ``gains``:
       the Baumgarte gains ``(alpha, beta)``, or None.
    9. The runner may append entries of its own after the formulation's state:
       with ``simulate(work=True)`` the work W of the non-conservative forces
       (:mod:`closedloop.simulation.work`).  ``rhs`` and ``unpack`` then see
       only the formulation's part, but a formulation that alters the steps
       (rule 7: it changes the state between steps, as a projection does)
       sees the whole state and must carry the entries after its own
       unchanged.

    A new formulation subclasses this class in one module of this package and
    adds itself to the registry (:data:`closedloop.formulations.REGISTRY`);
    one defined elsewhere is added with :func:`closedloop.formulations.register`.
    """

    guards_branch = False
    guards_partition = False

    @property
    @abstractmethod
    def name(self):
        """The formulation's one spelling (rule 1): a subclass sets it as a class attribute."""

    @property
    def gains(self):
        """``(alpha, beta)`` of Baumgarte's stabilisation (15), or None when there are none."""
        return None

    def pack(self, system, s, sd):
        """The integrator's state ``y = [s, s']`` (rule 2)."""
        return np.concatenate((s, sd))

    def state_names(self, system):
        """The names of the entries of ``y``: the coordinates, then their rates (rule 2)."""
        names = list(system.coordinate_names)
        return names + [f"d{name}/dt" for name in names]

    def unpacker(self, system):
        """A new :class:`StateUnpacker` for one segment (rule 3)."""
        return StateUnpacker(system.n)

    def make_rhs(self, system, mode, unpack):
        """``rhs(t, y) = [s', s'']`` on branch ``mode`` with s'' from :meth:`accelerations` (rule 4)."""
        accelerations = self.accelerations

        def rhs(t, y):
            s, sd = unpack(y, t)
            return np.concatenate((sd, accelerations(system, t, s, sd, mode)))

        return rhs

    @abstractmethod
    def accelerations(self, system, t, s, sd, mode=None):
        """s'' of this formulation at a consistent state (rule 5).

        Parameters
        ----------
        system : System
        t : float
        s, sd : ndarray, shape (n,)
            Coordinates and velocities.
        mode : tuple of bool, optional
            The branch of the switched force; None: the branch the state is on.

        Returns
        -------
        ndarray, shape (n,)
        """

    def switch_accelerations(self, system, mode):
        """A fast ``(t, s, sd) -> s''`` of (12) for switch decisions, or None (rule 6)."""
        return None

    def check_method(self, method):
        """Raise InputError for a method this formulation cannot run (rule 7); every method by default."""

    def integrator(self, system, method):
        """What solve_ivp runs for ``method`` (rule 7): the method itself by default."""
        return method
