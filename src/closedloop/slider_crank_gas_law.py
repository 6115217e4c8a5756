"""The gas force of section 4, written once: the printed law as sympy expressions.

The paper prints, for the slider moving out (``x_C' > 0``)::

    F = -282.857 / (6 - x_C) + 62.857                 1.5 <= x_C <= 5
    F = -110 [1 - sin 2 pi (x_C - 5.25)]              5 <= x_C <= 5.5

and F = 0 while the slider moves in or lies outside the stroke [1.5, 5.5] m.
Its constants live here and nowhere else.  The law is kept as two sympy
expressions in x_C with the coefficients ``a, b, c`` as symbols (a reading of
the data scales them, see :class:`closedloop.slider_crank.Reading`), and every
numeric form is generated from them by ``lambdify``, as the model's functions
are (:func:`closedloop.model.derive`):

- :func:`numeric_branches` ``("math")``: one state, for
  :meth:`GasForce.components <closedloop.slider_crank.GasForce.components>`;
- :func:`numeric_branches` ``("numpy")`` and :func:`law_many`: K states at once,
  for :func:`~closedloop.slider_crank.gas_force` and the basin map;
- :func:`branch_expression` and :func:`printed_law`: sympy, for the closed form
  (:class:`closedloop.ClosedForm`) and the ``sympy.physics.mechanics`` baseline;
- :func:`outward_work_functions`: the work on the outward branch, the integral
  of the same expressions (:mod:`closedloop.studies.energy`).

The angular wavenumber 2 pi of the ripple is a symbol too, given the number
``2.0 * math.pi`` in the numeric forms, so that they evaluate
``2 pi (x_C - 5.25)`` in that order (sympy would print ``pi (2 x_C - 10.5)``,
which rounds differently).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from .codecache import cached_code

__all__ = ["PRINTED_COEFFICIENTS", "STROKE", "CHANGE_POINT", "WAVENUMBER", "POSITION", "COEFFICIENTS",
           "INNER_LAW", "OUTER_LAW", "branch_expression", "printed_law", "numeric_branches", "law_many",
           "outward_work_functions"]

#: ``(a, b, c)`` of the law as printed, in the decimal reading: 282.857 N m, 62.857 N and 110 N.
PRINTED_COEFFICIENTS = (282.857, 62.857, 110.000)
#: Where the printed law holds: the inner and outer dead centres of Table 1's slider [m].
STROKE = (1.5, 5.5)
#: The slider position where the formula changes [m].
CHANGE_POINT = 5.0
#: The ripple's angular wavenumber 2 pi [rad/m], as the numeric forms use it.
WAVENUMBER = 2.0 * math.pi


@lru_cache(maxsize=None)
def _law():
    """The symbols and the two branches of the law, built (with sympy) on first use.

    The symbols of the law: the slider position x_C, the coefficients a, b, c and the
    wavenumber k. F on 1.5 <= x_C <= 5, for x_C' > 0: ``-a / (6 - x_C) + b``; F on
    5 <= x_C <= 5.5, for x_C' > 0: ``-c [1 - sin k (x_C - 5.25)]`` with k = 2 pi.
    """
    import sympy as sp

    position = sp.Symbol("x_C")
    coefficients = sp.symbols("a b c")
    wavenumber = sp.Symbol("k")
    inner = -coefficients[0] / (6 - position) + coefficients[1]
    outer = -coefficients[2] * (1 - sp.sin(wavenumber * (position - sp.Float(5.25))))
    return {"POSITION": position, "COEFFICIENTS": coefficients, "_WAVENUMBER_SYMBOL": wavenumber,
            "INNER_LAW": inner, "OUTER_LAW": outer, "_ARGUMENTS": (position, *coefficients, wavenumber)}


def __getattr__(name):
    """:data:`POSITION`, :data:`COEFFICIENTS`, :data:`INNER_LAW` and :data:`OUTER_LAW`, made by sympy on first use.

    The numeric forms do not need them when cached, so importing this module imports no sympy.
    """
    if name in ("POSITION", "COEFFICIENTS", "INNER_LAW", "OUTER_LAW", "_WAVENUMBER_SYMBOL", "_ARGUMENTS"):
        return _law()[name]
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def branch_expression(beyond_change, position, coefficients):
    """One branch of F as a sympy expression: the outer law if ``beyond_change``, else the inner one.

    Parameters
    ----------
    beyond_change : bool
        True for 5 <= x_C <= 5.5.
    position : sympy.Expr
        What stands for x_C (a coordinate symbol, or a dynamicsymbol).
    coefficients : tuple of float
        ``(a, b, c)`` of a reading, put in as sympy Floats.
    """
    import sympy as sp

    law = _law()["OUTER_LAW" if beyond_change else "INNER_LAW"]
    values = {symbol: sp.Float(value) for symbol, value in zip(_law()["COEFFICIENTS"], coefficients)}
    values[_law()["_WAVENUMBER_SYMBOL"]] = 2 * sp.pi
    values[_law()["POSITION"]] = position
    return law.subs(values)


def printed_law(position, rate, coefficients):
    """The whole printed law F(x_C, x_C') as one sympy ``Piecewise`` (no events: for the baseline).

    ``F = inner`` for ``x_C' > 0`` and 1.5 <= x_C <= 5, ``outer`` for ``x_C' > 0``
    and 5 < x_C <= 5.5, zero otherwise.
    """
    import sympy as sp

    low, high = STROKE
    return sp.Piecewise(
        (branch_expression(False, position, coefficients), (rate > 0) & (position >= low) & (position <= CHANGE_POINT)),
        (branch_expression(True, position, coefficients), (rate > 0) & (position > CHANGE_POINT) & (position <= high)),
        (0, True),
    )


@lru_cache(maxsize=None)
def numeric_branches(module):
    """``(inner, outer)``: the two branches of F generated by lambdify for ``module`` ("math" or "numpy").

    Each is called as ``branch(x, a, b, c, WAVENUMBER)``; the values are those
    of :data:`INNER_LAW` and :data:`OUTER_LAW`.  Kept in the disk cache
    (:mod:`closedloop.codecache`): sympy is needed only the first time.
    """
    def generate():
        import sympy as sp

        law = _law()
        return {name: sp.lambdify(law["_ARGUMENTS"], law[name.upper() + "_LAW"], modules=module)
                for name in ("inner", "outer")}

    made = cached_code("gas_law", (f"numeric_branches {module}",), generate, ("inner", "outer"))
    return made["inner"], made["outer"]


def law_many(position, beyond_change, coefficients):
    """F at K slider positions, each on its branch ``beyond_change[j]`` (arrays of shape (K,)).

    The inner branch is evaluated at ``x_C`` where ``x_C <= 5.5`` and at 5 elsewhere,
    so that its pole at x_C = 6 is never met outside the stroke; the caller
    sets F = 0 outside the stroke and for ``x_C' <= 0``.
    """
    inner, outer = numeric_branches("numpy")
    a, b, c = coefficients
    position = np.asarray(position, dtype=float)
    safe = np.where(position <= STROKE[1], position, CHANGE_POINT)
    return np.where(beyond_change, outer(position, a, b, c, WAVENUMBER), inner(safe, a, b, c, WAVENUMBER))


@lru_cache(maxsize=None)
def outward_work_functions():
    """``(inner, outer)`` work functions of F on the outward branch, integrated from the law by sympy.

    ``inner(x, a, b, c)`` is the integral of :data:`INNER_LAW` from x_C = 1.5 to
    ``x <= 5``; ``outer(x, a, b, c)`` that of :data:`OUTER_LAW` (k = 2 pi) from 5
    to ``x >= 5``.  Generated for numpy.
    """
    import sympy as sp

    INNER_LAW, OUTER_LAW, POSITION = _law()["INNER_LAW"], _law()["OUTER_LAW"], _law()["POSITION"]
    x = sp.Symbol("x")
    distance = sp.Symbol("distance", positive=True)          # 6 - x_C > 0 on the stroke: real logarithms
    start, change = sp.nsimplify(STROKE[0]), sp.nsimplify(CHANGE_POINT)
    inner_law = INNER_LAW.subs(POSITION, 6 - distance)
    inner = sp.integrate(inner_law, (distance, 6 - x, 6 - start))    # dx_C = -d(distance)
    outer = sp.integrate(OUTER_LAW.subs(_law()["_WAVENUMBER_SYMBOL"], 2 * sp.pi), (POSITION, change, x))
    arguments = (x, *_law()["COEFFICIENTS"])
    return (sp.lambdify(arguments, inner, modules="numpy"), sp.lambdify(arguments, outer, modules="numpy"))
