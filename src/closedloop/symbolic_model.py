"""The symbolic model of a closed-loop multibody system, and Lagrange's equations with multipliers derived from it.

Section 2 of the paper: a holonomic, scleronomic system is described by n
redundant coordinates ``s = [q; z]`` (1)-(4), f of them independent (``q``)
and r = n - f dependent (``z``), tied by r constraints ``f(s) = 0`` (6).
Lagrange's equations with multipliers read (5), (8)::

    M(s) s'' + Phi_s(s)^T lambda = p1(s, s', t),   p1 = tau - C s' - g   (7)

:class:`MultibodyModel` holds T, Pi, f(s), the independent coordinates and the
smooth forces as sympy expressions; :func:`derive` gives ``M``, ``p1``, ``f``,
``Phi_s`` and ``Phi_s' s'`` (the term of (10)-(11)) with their numeric functions
(:mod:`closedloop.model_code`).  sympy is imported only inside the functions
that need it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import Callable

import numpy as np

from .errors import InputError
from .validation import shown

__all__ = ["MultibodyModel", "DerivedModel", "derive"]


def _iterable(value):
    try:
        iter(value)
    except TypeError:
        return False
    return True


def _expression(name, value):
    """``value`` as a sympy expression, or an InputError naming ``name`` (a number is an expression too)."""
    import sympy as sp

    if isinstance(value, (str, bytes, bool)) or value is None:
        raise InputError(f"{name}: expected a sympy expression, got {shown(value)} ({type(value).__name__})")
    try:
        expression = sp.sympify(value, strict=True)
    except (sp.SympifyError, TypeError, ValueError):
        raise InputError(f"{name}: expected a sympy expression, got {shown(value)} ({type(value).__name__})") from None
    if not isinstance(expression, sp.Expr):
        raise InputError(f"{name}: expected a sympy expression, got {shown(value)} ({type(value).__name__})")
    return expression


@dataclass(frozen=True)
class MultibodyModel:
    """Symbolic description of a closed-loop multibody system (section 2).

    Parameters
    ----------
    coordinates : tuple of sympy.Symbol
        The n redundant coordinates ``s`` (1).
    velocities : tuple of sympy.Symbol
        Symbols standing for the time derivatives of ``coordinates``, in the
        same order.
    kinetic_energy : sympy.Expr
        T(s, s'), quadratic in the velocities.
    potential_energy : sympy.Expr
        Pi(s).
    constraints : tuple of sympy.Expr
        The r holonomic, scleronomic constraints ``f(s) = 0`` (6).
    independent : tuple of sympy.Symbol
        The f independent coordinates ``q`` (2); the rest are ``z`` (3).
    parameters : tuple of sympy.Symbol, optional
        Symbols whose numeric values are given later, when the model is bound
        into a :class:`System`.
    generalized_forces : tuple of sympy.Expr, optional
        Smooth non-conservative generalised forces ``tau(t, s, s')`` of (5),
        one per coordinate.  Forces that are not smooth expressions (switches,
        tables) are passed as Python callables to :class:`System` instead.
    time : sympy.Symbol, optional
        The time symbol used in ``generalized_forces`` (default ``t``).
    """

    coordinates: tuple
    velocities: tuple
    kinetic_energy: sp.Expr
    potential_energy: sp.Expr
    constraints: tuple
    independent: tuple
    parameters: tuple = ()
    generalized_forces: tuple | None = None
    time: sp.Symbol | None = None          # None: the symbol t (sympy is imported here only when a model is made)

    def __post_init__(self):
        import sympy as sp

        if self.time is None:
            object.__setattr__(self, "time", sp.Symbol("t"))
        for name in ("coordinates", "velocities", "constraints", "independent", "parameters"):
            value = getattr(self, name)
            if isinstance(value, (str, bytes)) or not _iterable(value):
                raise InputError(f"{name}: expected a sequence of sympy {'expressions' if name == 'constraints' else 'Symbols'}, "
                                 f"got {shown(value)}")
            object.__setattr__(self, name, tuple(value))
        for name in ("coordinates", "velocities", "independent", "parameters"):
            wrong = [v for v in getattr(self, name) if not isinstance(v, sp.Symbol)]
            if wrong:
                raise InputError(f"{name}: must be sympy Symbols (made with sympy.symbols), got {shown(wrong[0])} "
                                 f"({type(wrong[0]).__name__})")
        if not isinstance(self.time, sp.Symbol):
            raise InputError(f"time: must be a sympy Symbol, got {shown(self.time)} ({type(self.time).__name__})")
        for name in ("kinetic_energy", "potential_energy"):
            object.__setattr__(self, name, _expression(name, getattr(self, name)))
        object.__setattr__(self, "constraints", tuple(_expression("constraints", c) for c in self.constraints))
        if self.generalized_forces is not None:
            if isinstance(self.generalized_forces, (str, bytes)) or not _iterable(self.generalized_forces):
                raise InputError(f"generalized_forces: expected a sequence of sympy expressions, one per coordinate, "
                                 f"got {shown(self.generalized_forces)}")
            object.__setattr__(self, "generalized_forces",
                               tuple(_expression("generalized_forces", e) for e in self.generalized_forces))
        n, r = len(self.coordinates), len(self.constraints)
        if r >= n:
            raise InputError(f"constraints: {r} constraints on {n} coordinates leave no degree of freedom; a closed "
                             "loop has fewer constraints than coordinates (r < n)")
        if len(self.velocities) != n:
            raise InputError(f"velocities: need one per coordinate ({n}), got {len(self.velocities)}")
        if len(set(self.coordinates) | set(self.velocities)) != 2 * n:
            raise InputError("coordinates and velocities must be 2n distinct symbols")
        unknown = [q for q in self.independent if q not in self.coordinates]
        if unknown:
            raise InputError(f"independent: {unknown} are not among the coordinates")
        if len(self.independent) + r != n:
            raise InputError(
                f"independent: need n - r = {n} - {r} = {n - r} independent coordinates, "
                f"got {len(self.independent)}"
            )
        if self.generalized_forces is not None and len(self.generalized_forces) != n:
            raise InputError(f"generalized_forces: need one per coordinate ({n})")
        allowed = set(self.coordinates) | set(self.velocities) | set(self.parameters) | {self.time}
        geometric = set(self.coordinates) | set(self.parameters)
        for label, exprs, ok in (
            ("kinetic_energy", [self.kinetic_energy], allowed - {self.time}),
            ("potential_energy", [self.potential_energy], geometric),
            ("constraints", self.constraints, geometric),
            ("generalized_forces", self.generalized_forces or (), allowed),
        ):
            stray = set().union(*(sp.sympify(e).free_symbols for e in exprs)) - ok if exprs else set()
            if stray:
                raise InputError(
                    f"{label}: unexpected symbols {sorted(map(str, stray))}; declare them as "
                    "parameters (constraints must be holonomic and scleronomic: no velocities, no time)"
                )

    @property
    def independent_index(self) -> np.ndarray:
        """Positions of ``q`` within ``s``."""
        return np.array([self.coordinates.index(q) for q in self.independent], dtype=int)

    @property
    def dependent_index(self) -> np.ndarray:
        """Positions of ``z`` within ``s``."""
        return np.array([i for i, c in enumerate(self.coordinates) if c not in self.independent], dtype=int)


@dataclass(frozen=True)
class DerivedModel:
    """Lagrange's equations with multipliers of a :class:`MultibodyModel`.

    Attributes
    ----------
    model : MultibodyModel
    mass_matrix : sympy.Matrix
        M(s) of (5): the Hessian of T with respect to the velocities.
    p1 : sympy.Matrix
        p1 = tau - C s' - g of (7), with tau the smooth symbolic forces only.
    constraint_vector : sympy.Matrix
        f(s) of (6).
    jacobian : sympy.Matrix
        Phi_s = df/ds, r x n (9).
    jacobian_rate_product : sympy.Matrix
        Phi_s' s' of (10)-(11), so that p2 = -Phi_s' s'.
    dynamics : callable
        ``dynamics(t, s, sd, p) -> flat list`` of the entries of M, p1, f,
        Phi_s and Phi_s' s' (row by row), for one state given as lists of floats.
        Generated with the ``math`` module: for one state it is about four
        times faster than numpy on scalars.
    constraint_functions : callable
        ``constraint_functions(s, p) -> flat list`` of f and Phi_s, likewise.
    energies : callable
        ``energies(s, sd, p) -> [T, Pi]``, numpy: it takes whole trajectories.
    """

    model: MultibodyModel
    mass_matrix: sp.Matrix
    p1: sp.Matrix
    constraint_vector: sp.Matrix
    jacobian: sp.Matrix
    jacobian_rate_product: sp.Matrix
    dynamics: Callable
    constraint_functions: Callable
    energies: Callable

    def equations_of_motion(self, accelerations, multipliers) -> sp.Matrix:
        """Residual of (5) as sympy expressions: ``M s'' + Phi_s^T lambda - p1``.

        Parameters
        ----------
        accelerations : sequence of sympy.Symbol
            Symbols for s''.
        multipliers : sequence of sympy.Symbol
            Symbols for lambda.
        """
        import sympy as sp

        sdd = sp.Matrix(accelerations)
        lam = sp.Matrix(multipliers)
        return self.mass_matrix * sdd + self.jacobian.T * lam - self.p1


@lru_cache(maxsize=None)
def _symbolic_equations(model):
    """The sympy terms of (5)-(11): ``(M, p1, f, Phi_s, Phi_s' s', T, Pi)``, for :func:`derive`."""
    import sympy as sp

    s = sp.Matrix(model.coordinates)
    sd = sp.Matrix(model.velocities)
    T = sp.sympify(model.kinetic_energy)
    Pi = sp.sympify(model.potential_energy)
    n = len(s)

    M = sp.hessian(T, sd)
    if M.free_symbols & set(model.velocities):
        raise InputError("kinetic_energy: T must be quadratic in the velocities (M may not depend on them)")
    # d/dt(dT/ds') - M s'' = (d(M s')/ds) s'  (scleronomic: no explicit time in T)
    momentum = M * sd
    coriolis = momentum.jacobian(s) * sd - sp.Matrix([T]).jacobian(s).T      # C(s, s') s'
    gravity = sp.Matrix([Pi]).jacobian(s).T                                  # g(s)
    tau = sp.Matrix(model.generalized_forces) if model.generalized_forces else sp.zeros(n, 1)
    p1 = tau - coriolis - gravity                                            # (7)

    f = sp.Matrix(model.constraints)
    Phi = f.jacobian(s)                                                      # (9)
    gamma = (Phi * sd).jacobian(s) * sd                                      # Phi_s' s' of (10)
    return M, p1, f, Phi, gamma, T, Pi


def derive(model: MultibodyModel) -> DerivedModel:
    """Derive Lagrange's equations with multipliers (5)-(11); their numeric functions come with them.

    Runs once per model (the result is cached on the model, which is immutable).
    The numeric functions are those of :func:`closedloop.model.model_functions`: generated with
    common subexpressions eliminated, and loaded from the disk cache when a
    previous run generated them.

    Parameters
    ----------
    model : MultibodyModel

    Returns
    -------
    DerivedModel
    """
    if not isinstance(model, MultibodyModel):
        raise InputError(f"model: expected a MultibodyModel, got {type(model).__name__}")
    return _derive(model)


@lru_cache(maxsize=None)
def _derive(model):
    """:func:`derive`, once per model."""
    from .model_code import model_functions         # here: the generated code is made from this module's terms

    M, p1, f, Phi, gamma, _, _ = _symbolic_equations(model)
    functions = model_functions(model)
    return DerivedModel(model, M, p1, f, Phi, gamma, functions.dynamics, functions.constraint_functions,
                        functions.energies)


derive.cache_info, derive.cache_clear = _derive.cache_info, _derive.cache_clear     # one cache for both names
