"""Example mechanisms beyond the slider-crank, each a few lines of model description.

They show that the library is generic: a new closed loop is a :class:`MultibodyModel`,
not a new module of equations.
"""

from __future__ import annotations

from functools import lru_cache

from .model import MultibodyModel

__all__ = ["four_bar_model", "parameter_values"]


@lru_cache(maxsize=None)
def four_bar_model() -> MultibodyModel:
    """A planar four-bar linkage in a vertical plane: crank theta1, coupler theta2, rocker theta3.

    Three uniform slender bars of lengths l1, l2, l3 and masses m1, m2, m3 (moment of
    inertia m l^2/12 about the centre), pivoted at O = (0, 0) and D = (l0, 0); angles are
    measured counterclockwise from the x axis, so A = l1 (cos theta1, sin theta1) and
    B = (l0 + l3 cos theta3, l3 sin theta3). Gravity g acts along -y, Pi = 0 at y = 0.
    The loop closes (A + l2 (cos theta2, sin theta2) = B) with two constraints; theta1
    is independent.

    ``System(four_bar_model, values)`` (the function, not its model) loads the
    numeric functions from the disk cache without building the model.
    """
    import sympy as sp

    th1, th2, th3 = sp.symbols("theta1 theta2 theta3")
    w1, w2, w3 = sp.symbols("dtheta1 dtheta2 dtheta3")
    l0, l1, l2, l3, m1, m2, m3, g = sp.symbols("l0 l1 l2 l3 m1 m2 m3 g")
    x2 = l1 * sp.cos(th1) + l2 / 2 * sp.cos(th2)          # centre of the coupler
    y2 = l1 * sp.sin(th1) + l2 / 2 * sp.sin(th2)
    v2_sq = ((sp.diff(x2, th1) * w1 + sp.diff(x2, th2) * w2) ** 2
             + (sp.diff(y2, th1) * w1 + sp.diff(y2, th2) * w2) ** 2)
    T = m1 * l1**2 / 6 * w1**2 + m2 * v2_sq / 2 + m2 * l2**2 / 24 * w2**2 + m3 * l3**2 / 6 * w3**2
    Pi = g * (m1 * l1 / 2 * sp.sin(th1) + m2 * y2 + m3 * l3 / 2 * sp.sin(th3))
    loop = (l1 * sp.cos(th1) + l2 * sp.cos(th2) - l0 - l3 * sp.cos(th3),
            l1 * sp.sin(th1) + l2 * sp.sin(th2) - l3 * sp.sin(th3))
    return MultibodyModel(coordinates=(th1, th2, th3), velocities=(w1, w2, w3), kinetic_energy=T,
                          potential_energy=Pi, constraints=loop, independent=(th1,),
                          parameters=(l0, l1, l2, l3, m1, m2, m3, g))


def parameter_values(system):
    """The parameter values of a :class:`~closedloop.model.System` as a dict keyed by name."""
    return dict(zip(system.functions.parameters, system.parameter_values.tolist()))
