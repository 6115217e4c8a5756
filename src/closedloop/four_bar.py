"""Example mechanisms beyond the slider-crank, each a few lines of model description.

They show that the library is generic: a new closed loop is a :class:`MultibodyModel`,
not a new module of equations.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from .model import MultibodyModel

__all__ = ["points", "four_bar_model", "parameter_values"]


def points(s, values, module=np):
    """The named points of the four-bar at ``s = [theta1, theta2, theta3]``: its one home for positions.

    The model's loop constraints, potential energy and the coupler's kinetic energy are made
    from these points (:func:`four_bar_model`), and the drawings of :mod:`closedloop.plotting`
    draw them.

    Parameters
    ----------
    s : sequence of 3
        ``[theta1, theta2, theta3]`` [rad]: numbers, arrays of one shape (a point per entry), or
        sympy expressions.
    values : mapping
        ``l0``, ``l1``, ``l2``, ``l3`` [m] (other keys are ignored), e.g. :func:`parameter_values`;
        numbers or sympy symbols.
    module : module, optional
        Where ``cos`` and ``sin`` come from: numpy (default), math or sympy.

    Returns
    -------
    dict of str to (x, y)
        ``"O"`` and ``"D"``, the fixed pivots; ``"A"``, the crank pin; ``"B"``, the coupler's end
        reached from A along theta2; ``"C1"``, ``"C2"``, ``"C3"``, the centres of mass (the
        bars' midpoints); ``"rocker end"``, the rocker's end reached from D along theta3, which
        the loop constraints put at B.
    """
    theta1, theta2, theta3 = s[0], s[1], s[2]
    l0, l1, l2, l3 = values["l0"], values["l1"], values["l2"], values["l3"]
    zero = 0 * theta1
    crank = (module.cos(theta1), module.sin(theta1))
    coupler = (module.cos(theta2), module.sin(theta2))
    rocker = (module.cos(theta3), module.sin(theta3))
    pin = (l1 * crank[0], l1 * crank[1])
    return {
        "O": (zero, zero),
        "D": (l0 + zero, zero),
        "A": pin,
        "B": (pin[0] + l2 * coupler[0], pin[1] + l2 * coupler[1]),
        "C1": (l1 / 2 * crank[0], l1 / 2 * crank[1]),
        "C2": (pin[0] + l2 / 2 * coupler[0], pin[1] + l2 / 2 * coupler[1]),
        "C3": (l0 + l3 / 2 * rocker[0], l3 / 2 * rocker[1]),
        "rocker end": (l0 + l3 * rocker[0], l3 * rocker[1]),
    }


@lru_cache(maxsize=None)
def four_bar_model() -> MultibodyModel:
    """A planar four-bar linkage in a vertical plane: crank theta1, coupler theta2, rocker theta3.

    Three uniform slender bars of lengths l1, l2, l3 and masses m1, m2, m3 (moment of
    inertia m l^2/12 about the centre), pivoted at O = (0, 0) and D = (l0, 0); angles are
    measured counterclockwise from the x axis.  The positions are those of :func:`points`:
    the loop closes where the coupler's end B meets the rocker's end (two constraints), the
    centres of mass give Pi (gravity g along -y, Pi = 0 at y = 0) and the coupler's velocity;
    theta1 is independent.

    ``System(four_bar_model, values)`` (the function, not its model) loads the
    numeric functions from the disk cache without building the model.
    """
    import sympy as sp

    th1, th2, th3 = sp.symbols("theta1 theta2 theta3")
    w1, w2, w3 = sp.symbols("dtheta1 dtheta2 dtheta3")
    l0, l1, l2, l3, m1, m2, m3, g = sp.symbols("l0 l1 l2 l3 m1 m2 m3 g")
    at = points((th1, th2, th3), {"l0": l0, "l1": l1, "l2": l2, "l3": l3}, sp)
    x2, y2 = at["C2"]                                      # centre of the coupler
    v2_sq = ((sp.diff(x2, th1) * w1 + sp.diff(x2, th2) * w2) ** 2
             + (sp.diff(y2, th1) * w1 + sp.diff(y2, th2) * w2) ** 2)
    T = m1 * l1**2 / 6 * w1**2 + m2 * v2_sq / 2 + m2 * l2**2 / 24 * w2**2 + m3 * l3**2 / 6 * w3**2
    Pi = g * (m1 * at["C1"][1] + m2 * y2 + m3 * at["C3"][1])
    loop = tuple(end - rocker for end, rocker in zip(at["B"], at["rocker end"]))
    return MultibodyModel(coordinates=(th1, th2, th3), velocities=(w1, w2, w3), kinetic_energy=T,
                          potential_energy=Pi, constraints=loop, independent=(th1,),
                          parameters=(l0, l1, l2, l3, m1, m2, m3, g))


def parameter_values(system):
    """The parameter values of a :class:`~closedloop.model.System` as a dict keyed by name."""
    return dict(zip(system.functions.parameters, system.parameter_values.tolist()))
