"""The numeric functions of a model, generated from its derivation and kept on disk.

:func:`model_functions` lambdifies the terms of (5)-(11) of a
:class:`~closedloop.symbolic_model.MultibodyModel` (``math`` functions for one state,
numpy ones for many), with common subexpressions eliminated, and keeps their source in
the disk cache (:mod:`closedloop.codecache`), so that a later run loads them without
sympy.  A model is known to the cache by the function of this package that builds it,
or by its expressions.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from functools import lru_cache
from typing import Callable

from .codecache import cached_code
from .errors import InputError
from .symbolic_model import MultibodyModel, _symbolic_equations

__all__ = ["ModelFunctions", "model_functions", "array_functions"]


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
