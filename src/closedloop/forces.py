"""Generalised forces that are not smooth sympy expressions.

A force that switches (the paper's gas force acts only while x_C' > 0 and
changes formula at x_C = 5) is described by switching functions ``h_i(t, s, s')``.
Between two zeros of the h_i the force is smooth; ``mode[i]`` says on which
side of switch i the state is (``h_i > 0``).  :func:`closedloop.simulate`
freezes the mode during an integration segment, stops at each zero of an h_i
with an event, and then chooses the new mode, so that no step crosses a switch
blindly.
"""

from __future__ import annotations

import numpy as np

__all__ = ["SwitchedForce", "as_switched_force"]


class SwitchedForce:
    """Base class for a piecewise-smooth generalised force.

    Subclasses set :attr:`switch_names` and :attr:`can_stick` and implement
    :meth:`switching_functions` and :meth:`__call__`.

    Attributes
    ----------
    switch_names : tuple of str
        One readable name per switching function.
    can_stick : tuple of bool
        For each switch, whether the state may slide (stick) on its surface:
        only meaningful for velocity-level switches such as ``x_C' = 0``.
    """

    switch_names: tuple = ()
    can_stick: tuple = ()

    def switching_functions(self, t, s, sd) -> np.ndarray:
        """Values of the switching functions h_i at one state, shape (k,)."""
        return np.empty(0)

    def switching_values(self, t, s, sd) -> list:
        """The values of :meth:`switching_functions` as a list of Python floats.

        Evaluated after every accepted step of the compiled runner
        (:mod:`closedloop.simulation.dop853_runner`); override it for speed (the
        default converts the array of :meth:`switching_functions`).  It must give
        the same numbers.
        """
        values = self.switching_functions(t, s, sd)
        return values.tolist() if isinstance(values, np.ndarray) else list(values)

    def __call__(self, t, s, sd, mode) -> np.ndarray:
        """The generalised force, shape (n,), on the smooth branch ``mode``."""
        raise NotImplementedError

    def components(self, t, s, sd, mode) -> list:
        """The force of :meth:`__call__` as a list of floats, for lists ``s``, ``sd``.

        Used by the generated right-hand side of
        :class:`closedloop.formulations.ClosedForm`, which works on floats;
        override it for speed (the default goes through :meth:`__call__` on arrays).
        """
        return np.asarray(self(t, np.asarray(s, dtype=float), np.asarray(sd, dtype=float), mode),
                          dtype=float).tolist()

    def expressions(self, mode, time, coordinates, velocities):
        """The force on branch ``mode`` as n sympy expressions, or None (the default) if it has none.

        ``time``, ``coordinates`` and ``velocities`` are the model's symbols.
        :func:`closedloop.formulations.closed_form.closed_form_rhs` folds these expressions
        into its generated right-hand side; they must equal :meth:`__call__` on
        that branch.
        """
        return None

    def cache_key(self, mode):
        """A string that fixes :meth:`expressions` on branch ``mode``, or None (the default).

        Code generated from the expressions (the forcing period of
        :func:`closedloop.simulation.switching.forcing_period`, the closed form's
        right-hand sides) is kept on disk under this key and the package's
        source (:mod:`closedloop.codecache`), so it must change whenever the
        expressions could: name the class and every number they use.  Two
        branches with the same key share one generated function.  A force of a
        class defined outside this package has its source outside the key:
        leave it None there, and the code is generated again in every run.
        """
        return None

    def switching_functions_many(self, t, s, sd) -> np.ndarray:
        """The h_i at K states, shape (k, K); ``s``, ``sd`` of shape (n, K), t a float or (K,).

        The default evaluates :meth:`switching_functions` state by state;
        a subclass may override it with an array expression.
        """
        times = np.broadcast_to(np.asarray(t, dtype=float), s.shape[1:])
        columns = [self.switching_functions(times[j], s[:, j], sd[:, j]) for j in range(s.shape[1])]
        return np.array(columns, dtype=float).reshape(s.shape[1], -1).T

    def many(self, t, s, sd, mode) -> np.ndarray:
        """The generalised force at K states, shape (n, K), each on its own branch.

        ``mode`` is a boolean array of shape (k, K): column j is the branch of
        state j.  The default calls the force state by state; a subclass may
        override it with an array expression.
        """
        times = np.broadcast_to(np.asarray(t, dtype=float), s.shape[1:])
        columns = [self(times[j], s[:, j], sd[:, j], tuple(bool(m) for m in mode[:, j]))
                   for j in range(s.shape[1])]
        return np.array(columns, dtype=float).reshape(s.shape[1], s.shape[0]).T

    def mode_at(self, t, s, sd) -> tuple:
        """The branch on which a state lies strictly off every switch surface."""
        return tuple(bool(h > 0) for h in self.switching_functions(t, s, sd))


class _SmoothForce(SwitchedForce):
    """A plain callable ``force(t, s, sd)`` with no switches."""

    def __init__(self, function, n):
        self.function = function
        self.n = n

    def __call__(self, t, s, sd, mode=()):
        value = np.asarray(self.function(t, s, sd), dtype=float)
        if value.shape != (self.n,):
            raise ValueError(f"force: must return an array of shape ({self.n},), got {value.shape}")
        return value


def as_switched_force(force, n):
    """Wrap ``force`` as a :class:`SwitchedForce` (``None`` stays ``None``)."""
    if force is None or isinstance(force, SwitchedForce):
        return force
    if not callable(force):
        raise TypeError("force: expected a SwitchedForce or a callable force(t, s, sd)")
    return _SmoothForce(force, n)
