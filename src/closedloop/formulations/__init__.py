"""The formulations of Lagrange's equations with multipliers, and their registry.

Each formulation is a small immutable object over the same
:class:`~closedloop.model.System` that keeps the contract of
:class:`~closedloop.formulations.base.Formulation`:

- :class:`Augmented`: the augmented system (12), no stabilisation;
- :class:`Baumgarte`: (16)-(17), the constraint error obeys (15);
- :class:`Orthogonal`: the ODE (24)-(26), lambda removed with R of (20);
- :class:`NullSpace`: (24)-(26) with a null-space basis of Phi_s in place of R,
  so it passes the dead positions where Phi_z of (20) is singular;
- :class:`Minimal`: coordinate partitioning, an ODE in q alone with z from
  Newton on f = 0 at every evaluation: the accuracy reference;
- :class:`ClosedForm`: the accelerations of (26) eliminated symbolically and
  generated as one function: the fast one;
- :class:`Projected`: (12) with every step projected back onto f = 0, f' = 0.

A new formulation is one module of this package and one line of :data:`REGISTRY`; a
formulation defined outside the package joins it with :func:`register`.
"""

from __future__ import annotations

import inspect

from ..errors import InputError
from ..validation import one_of
from .base import Formulation, StateUnpacker
from .closed_form import ClosedForm
from .minimal import Minimal
from .projected import Projected, project_state
from .redundant import Augmented, Baumgarte, NullSpace, Orthogonal, baumgarte_from_step, baumgarte_p2

__all__ = [
    "Formulation", "StateUnpacker", "Augmented", "Baumgarte", "Orthogonal", "NullSpace", "Minimal", "ClosedForm",
    "Projected", "project_state", "baumgarte_from_step", "baumgarte_p2", "formulation_from_name",
    "FORMULATION_NAMES", "REGISTRY", "register",
]

#: Every formulation by its one name (its class attribute ``name``), in the book's order.
REGISTRY = {cls.name: cls for cls in (Augmented, Baumgarte, Orthogonal, Minimal, NullSpace, ClosedForm, Projected)}
#: The names of the library's own formulations (the command line's choices).
FORMULATION_NAMES = tuple(REGISTRY)


def register(cls):
    """Add the formulation class ``cls`` to :data:`REGISTRY` under its ``name``; returns ``cls``.

    Usable as a class decorator.  :func:`formulation_from_name` then makes it,
    as it makes the library's own.

    Parameters
    ----------
    cls : type
        A concrete subclass of :class:`Formulation` that can be made with no
        arguments, whose ``name`` is a string no registered formulation has.

    Raises
    ------
    InputError
        If ``cls`` is not such a class.
    """
    if not (isinstance(cls, type) and issubclass(cls, Formulation)) or inspect.isabstract(cls):
        raise InputError(f"cls: expected a concrete subclass of Formulation, got {cls!r}")
    name = cls.name
    if not isinstance(name, str) or not name:
        raise InputError(f"cls: {cls.__name__}.name must be a non-empty string, got {name!r}")
    if REGISTRY.get(name, cls) is not cls:
        raise InputError(f"cls: the name {name!r} is {REGISTRY[name].__name__}'s already")
    try:
        cls()                               # rule 1: formulation_from_name(result.formulation) makes it so
    except TypeError as error:
        raise InputError(f"cls: {cls.__name__}() must work without arguments ({error})") from None
    REGISTRY[name] = cls
    return cls


def _takes_gains(cls):
    """Whether the formulation ``cls`` takes Baumgarte gains: its ``gains`` flag, on a default instance."""
    return cls().gains is not None


def formulation_from_name(name, alpha=None, beta=None):
    """The formulation called ``name``, with Baumgarte gains where it takes them.

    Parameters
    ----------
    name : str
        A key of :data:`REGISTRY`; ``SimulationResult.formulation`` is one.
    alpha, beta : float, optional
        Only for the formulations that take gains (default 5 and 5, Baumgarte's choice).
    """
    cls = REGISTRY[one_of("formulation", name, tuple(REGISTRY))]
    gains = {k: v for k, v in (("alpha", alpha), ("beta", beta)) if v is not None}
    if gains and not _takes_gains(cls):
        takers = ", ".join(n for n, c in REGISTRY.items() if _takes_gains(c))
        raise InputError(f"alpha, beta: only the {takers} formulations take gains, not {name!r}")
    return cls(**gains)
