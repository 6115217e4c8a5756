"""A closed-loop multibody system in numbers: a model bound to parameter values and forces.

:class:`System` evaluates the terms of Lagrange's equations with multipliers (5)-(11)
(:class:`Dynamics`: M, p1, f, Phi_s, Phi_s' s') at one state or at many, from the
model's generated functions (:mod:`closedloop.model_code`), which a cached model loads
without sympy.  The symbolic model and its derivation are in
:mod:`closedloop.symbolic_model`; this module gives their names too.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import NamedTuple

import numpy as np

from .errors import InputError
from .forces import as_switched_force
from .linalg import CONDITION_LIMIT, condition_number, orthogonal_complement, solve_augmented
from .model_code import ModelFunctions, _build, array_functions, model_functions
from .symbolic_model import DerivedModel, MultibodyModel, derive
from .validation import finite_number

__all__ = ["MultibodyModel", "DerivedModel", "derive", "System", "Dynamics", "ModelFunctions", "model_functions",
           "array_functions", "condition_number", "CONDITION_LIMIT"]


class Dynamics(NamedTuple):
    """The terms of Lagrange's equations with multipliers (8)-(11) at one state (or at K states).

    A tuple, so ``M, p1, constraint_values, Phi, gamma = system.dynamics(...)``
    unpacks it; the names keep the constraint vector f of (6) apart from
    ``System.f``, the number of degrees of freedom.

    Attributes
    ----------
    mass_matrix : ndarray, shape (n, n)
        M(s) of (8).
    p1 : ndarray, shape (n,)
        ``tau - C s' - g`` of (7), the switched force included.
    constraints : ndarray, shape (r,)
        f(s) of (6).
    jacobian : ndarray, shape (r, n)
        Phi_s of (9).
    jacobian_rate_product : ndarray, shape (r,)
        ``Phi_s' s'`` of (10)-(11).
    """

    mass_matrix: np.ndarray
    p1: np.ndarray
    constraints: np.ndarray
    jacobian: np.ndarray
    jacobian_rate_product: np.ndarray


def _stack(values, size):
    """Entries (numbers or arrays of shape (size,)) as one float array of shape (len(values), size)."""
    out = np.empty((len(values), size))
    for k, value in enumerate(values):
        out[k] = value
    return out


class System:
    """A model bound to parameter values and to non-smooth forces.

    Parameters
    ----------
    model : MultibodyModel, or a function without arguments that returns one
        Given a function (such as :func:`closedloop.slider_crank.slider_crank_model`),
        the system takes its numeric functions from the disk cache when they are
        there, and builds the symbolic model (with sympy) only when asked for
        :attr:`model` or :attr:`derived`, or to generate them.
    parameter_values : mapping of sympy.Symbol or str to float
        A value for every symbol in ``model.parameters``.
    force : SwitchedForce or callable, optional
        Generalised forces that are not smooth sympy expressions, added to
        p1 of (7).  A plain callable ``force(t, s, sd) -> array (n,)`` is taken
        as smooth; a :class:`closedloop.forces.SwitchedForce` declares where it
        switches, so that :func:`closedloop.simulate` stops at every switch.

    Attributes
    ----------
    functions : ModelFunctions
        The model's numeric functions and the names of its symbols.
    coordinate_names : tuple of str
        The names of the coordinates s, in order.
    """

    def __init__(self, model, parameter_values=None, force=None):
        if not isinstance(model, MultibodyModel) and not callable(model):
            raise InputError(f"model: expected a MultibodyModel or a function that returns one, got "
                             f"{type(model).__name__}")
        functions = None if isinstance(model, MultibodyModel) else model_functions(model)
        names = [str(p) for p in model.parameters] if functions is None else list(functions.parameters)
        if parameter_values is None:
            parameter_values = {}
        if not isinstance(parameter_values, Mapping):
            raise InputError(f"parameter_values: expected a mapping of parameter names to numbers, got "
                             f"{type(parameter_values).__name__}")
        by_name = {str(k): v for k, v in parameter_values.items()}
        missing = [name for name in names if name not in by_name]
        if missing:
            raise InputError(f"parameter_values: missing values for {missing}")
        values = np.array([finite_number(f"parameter_values[{name!r}]", by_name[name]) for name in names],
                          dtype=float)
        self.functions = model_functions(model) if functions is None else functions
        self._model = model if isinstance(model, MultibodyModel) else None
        self._builder = None if isinstance(model, MultibodyModel) else model
        self.parameter_values = values
        self._parameter_list = values.tolist()      # the generated math-module code is fastest on floats
        self.coordinate_names = self.functions.coordinates
        self.n = len(self.coordinate_names)
        self.r = self.functions.constraint_count
        self.f = self.n - self.r
        self.force = as_switched_force(force, self.n)
        self.q_index = np.array(self.functions.independent_index, dtype=int)
        self.z_index = np.array(self.functions.dependent_index, dtype=int)
        #: Functions generated for this system (closed forms, determinants), kept by their makers
        #: under their own keys: built once per system, never shared between systems.
        self.generated = {}

    @property
    def model(self) -> MultibodyModel:
        """The symbolic model (sympy), built on first use when the system was given a function."""
        if self._model is None:
            self._model = _build(self._builder)
        return self._model

    @property
    def derived(self) -> DerivedModel:
        """The model's derivation, :func:`derive` (sympy), on first use."""
        return derive(self.model)

    @property
    def model_identity(self) -> str:
        """What the disk cache knows this system's model by (see :func:`model_functions`), or None."""
        return self.functions.identity

    # -- numeric building blocks ------------------------------------------------
    def dynamics(self, t, s, sd, mode=None):
        """``(M, p1, f, Phi_s, Phi_s' s')`` of (7)-(11) at one state, p1 including the switched force.

        Returns a :class:`Dynamics`, a named tuple of these five.

        Parameters
        ----------
        t : float
        s, sd : ndarray, shape (n,)
        mode : tuple of bool, optional
            The branch of each switch of the force (see :mod:`closedloop.forces`);
            by default the branch the state lies on.
        """
        n, r = self.n, self.r
        values = np.array(self.functions.dynamics(float(t), s.tolist(), sd.tolist(), self._parameter_list))
        M = values[: n * n].reshape(n, n)
        p1 = values[n * n: n * n + n]
        constraint_values = values[n * n + n: n * n + n + r]
        Phi = values[n * n + n + r: n * n + n + r + r * n].reshape(r, n)
        gamma = values[n * n + n + r + r * n:]
        if self.force is not None:
            if mode is None:
                mode = self.force.mode_at(t, s, sd)
            p1 = p1 + self.force(t, s, sd, mode)
        return Dynamics(M, p1, constraint_values, Phi, gamma)

    def applied_forces(self, t, s, sd, mode=None):
        """tau of (5) at one state: the non-conservative generalised forces, shape (n,).

        The model's smooth ``generalized_forces`` plus the switched force on the
        branch ``mode`` (by default the branch the state lies on).  Their power
        ``tau . s'`` is the rate of change of T + Pi along an exact motion (the
        constraint forces do no work while f' = 0).
        """
        tau = np.zeros(self.n)
        function = self.functions.generalized_forces
        if function is not None:
            tau += np.array(function(float(t), np.asarray(s, dtype=float).tolist(),
                                     np.asarray(sd, dtype=float).tolist(), self._parameter_list), dtype=float)
        if self.force is not None:
            if mode is None:
                mode = self.force.mode_at(t, s, sd)
            tau += self.force(t, s, sd, mode)
        return tau

    def dynamics_many(self, t, s, sd):
        """``(M, p1, f, Phi_s, Phi_s' s')`` at K states at once, without the switched force.

        Parameters
        ----------
        t : float or ndarray, shape (K,)
        s, sd : ndarray, shape (n, K)

        Returns
        -------
        Dynamics
            Its fields with a last axis of length K: M (n, n, K); p1 (n, K), the
            smooth forces only (add ``system.force.many(...)`` for the switched
            one); f (r, K); Phi_s (r, n, K); Phi_s' s' (r, K).
        """
        n, r = self.n, self.r
        size = s.shape[1]
        dynamics = self.functions.dynamics_many
        values = _stack(dynamics(t, list(s), list(sd), self._parameter_list), size)
        split = np.cumsum([n * n, n, r, r * n])
        M, p1, constraint_values, Phi, gamma = np.split(values, split)
        return Dynamics(M.reshape(n, n, size), p1, constraint_values, Phi.reshape(r, n, size), gamma)

    def constraints_and_jacobian_many(self, s):
        """``(f, Phi_s)`` of (6) and (9) at K configurations: shapes (r, K) and (r, n, K)."""
        size = s.shape[1]
        values = _stack(self.functions.constraint_functions_many(list(s), self._parameter_list), size)
        return values[: self.r], values[self.r:].reshape(self.r, self.n, size)

    def constraints(self, s):
        """f(s) of (6)."""
        return self.constraints_and_jacobian(s)[0]

    def constraints_and_jacobian(self, s):
        """``(f(s), Phi_s(s))`` of (6) and (9)."""
        values = np.array(self.functions.constraint_functions(np.asarray(s, dtype=float).tolist(),
                                                            self._parameter_list))
        return values[: self.r], values[self.r:].reshape(self.r, self.n)

    def constraint_errors(self, s, sd):
        """``(|f|, |Phi_s s'|)`` of (32) and (9) at every column of ``s``, ``sd`` (n x N)."""
        f, Phi = self.constraints_and_jacobian_many(np.asarray(s, dtype=float))
        velocity = np.einsum("ijk,jk->ik", Phi, sd)
        return np.sqrt(np.sum(f * f, axis=0)), np.sqrt(np.sum(velocity * velocity, axis=0))

    def jacobian(self, s):
        """Phi_s(s) of (9), r x n."""
        return self.constraints_and_jacobian(s)[1]

    def orthogonal_complement(self, s):
        """R(s) of (20): ``[E; -Phi_z^{-1} Phi_q]``, placed in the order of ``s``.

        Satisfies Phi_s R = 0 (18).  Raises
        :class:`~closedloop.errors.SingularConfigurationError` if Phi_z is singular.
        """
        return orthogonal_complement(self.jacobian(s), self.q_index, self.z_index)

    def energy(self, s, sd):
        """T + Pi at one state or at many (arrays of shape (n, N))."""
        T, Pi = self.functions.energies(s, sd, self.parameter_values)
        return np.asarray(T, dtype=float) + np.asarray(Pi, dtype=float)

    def kinetic_and_potential_energy(self, s, sd):
        """``(T, Pi)`` at one state or at many (arrays of shape (n, N))."""
        T, Pi = self.functions.energies(s, sd, self.parameter_values)
        return np.asarray(T, dtype=float), np.asarray(Pi, dtype=float)

    def constrained_accelerations(self, t, s, sd, mode=None, p2=None):
        """Solve the augmented system (12) or (16) for ``(s'', lambda)``.

        Parameters
        ----------
        p2 : ndarray, optional
            Right-hand side of the constraint rows; ``-Phi_s' s'`` of (11) when
            omitted, Baumgarte's p2~ of (17) when given.
        """
        M, p1, _, Phi, gamma = self.dynamics(t, s, sd, mode)
        rhs2 = -gamma if p2 is None else p2
        return solve_augmented(M, Phi, p1, rhs2, t)
