"""Symbolic model of a closed-loop multibody system, and its numeric form.

Section 2 of the paper: a holonomic, scleronomic system is described by n
redundant coordinates ``s = [q; z]`` (1)-(4), f of them independent (``q``)
and r = n - f dependent (``z``), tied by r constraints ``f(s) = 0`` (6).
Lagrange's equations with multipliers read (5), (8)::

    M(s) s'' + Phi_s(s)^T lambda = p1(s, s', t),   p1 = tau - C s' - g   (7)

This module turns a symbolic description (T, Pi, constraints, forces) into
fast numeric functions for ``M``, ``p1``, ``f``, ``Phi_s`` and
``Phi_s' s'`` (the term of (10)-(11)).  The derivation runs once per model;
its generated functions are kept on disk (:mod:`closedloop.codecache`), so
that a later run loads them without sympy, and every numeric call is plain
Python or numpy.  sympy is imported only where a derivation is needed: a
:class:`System` of a cached model never imports it.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Callable, NamedTuple

import numpy as np

from .codecache import cached_code
from .errors import InputError
from .forces import as_switched_force
from .linalg import CONDITION_LIMIT, condition_number, orthogonal_complement, solve_augmented
from .validation import finite_number, shown

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
    The numeric functions are those of :func:`model_functions`: generated with
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
    M, p1, f, Phi, gamma, _, _ = _symbolic_equations(model)
    functions = model_functions(model)
    return DerivedModel(model, M, p1, f, Phi, gamma, functions.dynamics, functions.constraint_functions,
                        functions.energies)


derive.cache_info, derive.cache_clear = _derive.cache_info, _derive.cache_clear     # one cache, as before


@dataclass(frozen=True)
class ModelFunctions:
    """The numeric functions of a model, and the names that go with them: all a :class:`System` needs.

    Made by :func:`model_functions` from the derivation of (5)-(11), or loaded
    from the disk cache without sympy.

    Attributes
    ----------
    identity : str or None
        What the disk cache knows the model by (see :func:`model_functions`); None
        for a model whose code is not kept on disk.
    coordinates, velocities, parameters : tuple of str
        The names of the model's symbols, in order.
    independent_index, dependent_index : tuple of int
        Positions of ``q`` and ``z`` within ``s``.
    constraint_count : int
        r, the number of constraints (6).
    dynamics, constraint_functions, energies : callable
        As the attributes of :class:`DerivedModel` of the same names.
    dynamics_many, constraint_functions_many : callable
        The same entries as ``dynamics`` and ``constraint_functions``, generated for
        numpy arrays (:func:`array_functions`).
    generalized_forces : callable or None
        ``generalized_forces(t, s, sd, p) -> list`` of the smooth forces tau of (5)
        (``math`` module), None for a model without them.
    """

    identity: str
    coordinates: tuple
    velocities: tuple
    parameters: tuple
    independent_index: tuple
    dependent_index: tuple
    constraint_count: int
    dynamics: Callable
    constraint_functions: Callable
    energies: Callable
    dynamics_many: Callable
    constraint_functions_many: Callable
    generalized_forces: Callable | None


#: The names a cached entry of a model defines.
_MODEL_NAMES = ("coordinates", "velocities", "parameters", "independent_index", "dependent_index",
                "constraint_count", "dynamics", "constraint_functions", "energies", "dynamics_many",
                "constraint_functions_many", "generalized_forces")


def _is_builder(model):
    """True for a function that builds a model, rather than a model."""
    return callable(model) and not isinstance(model, MultibodyModel)


def _build(builder):
    """The model a builder function returns, checked."""
    model = builder()
    if not isinstance(model, MultibodyModel):
        raise InputError(f"model: {getattr(builder, '__qualname__', builder)!r} returned "
                         f"{type(model).__name__}, not a MultibodyModel")
    return model


def _identity(model):
    """The model's part of the cache key.

    A function of this package that builds a model is known by its name: its
    definition is this package's source, which is in every key already.  Any
    other model is known by the sha256 of ``srepr`` of its fields, which spells
    out every expression and every symbol's assumptions; unless an expression
    uses a class defined outside sympy (a function of one's own, whose code
    ``srepr`` does not show): then None, and its code is not kept on disk.
    """
    if _is_builder(model) and getattr(model, "__module__", "").partition(".")[0] == "closedloop":
        return f"builder {model.__module__}.{model.__qualname__}"
    if _is_builder(model):
        model = _build(model)
    import sympy as sp

    fields = sp.Tuple(*model.coordinates, *model.velocities, model.kinetic_energy, model.potential_energy,
                      *model.constraints, *model.parameters, *(model.generalized_forces or ()), model.time)
    if any(not (type(node).__module__ or "").startswith("sympy.") for node in sp.preorder_traversal(fields)):
        return None
    fields = (model.coordinates, model.velocities, model.kinetic_energy, model.potential_energy,
              model.constraints, model.independent, model.parameters, model.generalized_forces, model.time)
    return f"srepr sha256 {hashlib.sha256(sp.srepr(fields).encode()).hexdigest()}"


@lru_cache(maxsize=None)
def model_functions(model) -> ModelFunctions:
    """The numeric functions of a model, from the disk cache or generated now (then cached).

    Parameters
    ----------
    model : MultibodyModel, or a function without arguments that returns one
        A function of this package (such as
        :func:`closedloop.slider_crank.slider_crank_model`) is called only when
        its functions are not cached yet: a cached model needs no sympy.

    Returns
    -------
    ModelFunctions
        Cached per model (or function) within a run; on disk unless the model
        uses a class defined outside sympy (see :func:`_identity`).
    """
    identity = _identity(model)
    made = cached_code("model", (identity,), lambda: _generate(_build(model) if _is_builder(model) else model),
                       _MODEL_NAMES)
    return ModelFunctions(identity, **made)


def _generate(model):
    """Derive the model and generate its numeric functions (with sympy), for :func:`model_functions`."""
    import sympy as sp

    M, p1, f, Phi, gamma, T, Pi = _symbolic_equations(model)
    args = [model.time, list(model.coordinates), list(model.velocities), list(model.parameters)]
    flat = [*M, *p1, *f, *Phi, *gamma]
    forces = model.generalized_forces
    return {
        "coordinates": tuple(map(str, model.coordinates)),
        "velocities": tuple(map(str, model.velocities)),
        "parameters": tuple(map(str, model.parameters)),
        "independent_index": tuple(model.independent_index.tolist()),
        "dependent_index": tuple(model.dependent_index.tolist()),
        "constraint_count": len(model.constraints),
        "dynamics": sp.lambdify(args, flat, modules="math", cse=True),
        "constraint_functions": sp.lambdify(args[1:2] + args[3:], [*f, *Phi], modules="math", cse=True),
        "energies": sp.lambdify(args[1:], [T, Pi], modules="numpy", cse=True),
        "dynamics_many": sp.lambdify(args, flat, modules="numpy", cse=True),
        "constraint_functions_many": sp.lambdify(args[1:2] + args[3:], [*f, *Phi], modules="numpy", cse=True),
        "generalized_forces": None if forces is None else sp.lambdify(args, list(forces), modules="math"),
    }


def array_functions(model):
    """The numeric functions of :func:`derive`, generated for numpy arrays.

    The same sympy expressions as ``DerivedModel.dynamics`` and
    ``DerivedModel.constraint_functions``, lambdified with numpy instead of
    ``math``, so that one call evaluates many states at once (arrays of
    shape (K,) in place of each coordinate).  Entries that do not depend on
    the state come back as plain numbers; :meth:`System.dynamics_many`
    broadcasts them.  Cached with the others (:func:`model_functions`).

    Returns
    -------
    (dynamics, constraint_functions) : tuple of callables
        With the signatures of the ``DerivedModel`` attributes of the same names.
    """
    functions = model_functions(model)
    return functions.dynamics_many, functions.constraint_functions_many


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
