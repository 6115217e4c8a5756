"""The cubic Hermite interpolant over one step, and its roots: written once.

Between two step ends a quantity g (a switching function, a coordinate) is
known with its values ``g0, g1`` and its slopes.  Per unit of the step
(``u = (t - t0) / (t1 - t0)`` in [0, 1], slopes ``d0, d1`` multiplied by the
step) the cubic Hermite interpolant is

    p(u) = (1 + 2u)(1 - u)^2 g0 + u (1 - u)^2 d0 + u^2 (3 - 2u) g1 - u^2 (1 - u) d1.

It locates where a switching function crosses zero inside a step (the
compiled DOP853's events, the basin map's batch integrator), where the path
meets a change point (:mod:`closedloop.simulation.change_points`), and the
turning points of a one-sided force's coordinate (:mod:`closedloop.studies.energy`).
Every function takes numbers or arrays of one shape (K states at once).

Where the second derivatives at the ends are known too (the accelerations of a
step's end states), the quintic Hermite interpolant (:func:`quintic_values`,
:func:`quintic_slopes`) matches them as well, with an error of order h^6
instead of h^4: the watch along a run's steps (:mod:`closedloop.simulation.watch`)
locates a crossing of det Phi_z = 0 and a turning point of the independent
coordinates on it.
"""

from __future__ import annotations

import numpy as np

__all__ = ["values", "slopes", "quintic_values", "quintic_slopes", "first_root", "turning_point", "ROOT_TOLERANCE",
           "SAMPLES"]

#: Roots are refined until the bracket, or the Newton step, is below this (per unit of the step).
ROOT_TOLERANCE = 1e-13
#: The cubic is sampled at this many equal parts of the step first, so that of several roots in
#: one step the earliest is taken.
SAMPLES = 8
_MAX_ITERATIONS = 60
#: Up to this many roots are refined one by one (:func:`_first_root_of_one`, the same arithmetic): the
#: arrays' loop costs some 20 numpy calls an iteration whatever their size, and the basin map's steps
#: rarely have more than a few cells at a switch.
_FEW = 8


def values(u, g0, g1, d0, d1):
    """p(u) of the interpolant with values g0, g1 and slopes (per unit) d0, d1."""
    v = 1.0 - u
    return (1.0 + 2.0 * u) * v * v * g0 + u * v * v * d0 + u * u * (3.0 - 2.0 * u) * g1 - u * u * v * d1


def slopes(u, g0, g1, d0, d1):
    """dp/du of the interpolant."""
    return 6.0 * u * (u - 1.0) * (g0 - g1) + (1.0 - u) * (1.0 - 3.0 * u) * d0 + u * (3.0 * u - 2.0) * d1


def quintic_values(u, g0, g1, d0, d1, c0, c1):
    """The quintic Hermite interpolant with values g0, g1, slopes d0, d1 and second derivatives c0, c1.

    Per unit of the step, like :func:`values`: the slopes are multiplied by the
    step h, the second derivatives by h^2.
    """
    u2 = u * u
    u3 = u2 * u
    v3 = (1.0 - u) ** 3
    return (v3 * (g0 + u * (3.0 * g0 + d0) + u2 * (6.0 * g0 + 3.0 * d0 + 0.5 * c0))
            + u3 * (g1 + (1.0 - u) * (3.0 * g1 - d1) + (1.0 - u) ** 2 * (6.0 * g1 - 3.0 * d1 + 0.5 * c1)))


def quintic_slopes(u, g0, g1, d0, d1, c0, c1):
    """d/du of :func:`quintic_values`."""
    w = 1.0 - u
    u2 = u * u
    inner0 = g0 + u * (3.0 * g0 + d0) + u2 * (6.0 * g0 + 3.0 * d0 + 0.5 * c0)
    inner1 = g1 + w * (3.0 * g1 - d1) + w * w * (6.0 * g1 - 3.0 * d1 + 0.5 * c1)
    return (-3.0 * w * w * inner0 + w ** 3 * (3.0 * g0 + d0 + 2.0 * u * (6.0 * g0 + 3.0 * d0 + 0.5 * c0))
            + 3.0 * u2 * inner1 + u2 * u * (-(3.0 * g1 - d1) - 2.0 * w * (6.0 * g1 - 3.0 * d1 + 0.5 * c1)))


def first_root(g0, g1, d0, d1):
    """The earliest u in [0, 1] where the interpolant is zero, for ends that bracket a zero.

    The cubic is sampled at :data:`SAMPLES` points; in the first part where it
    changes sign, safeguarded Newton (bisection whenever Newton would leave
    the bracket) refines the root to :data:`ROOT_TOLERANCE`.  ``g0 == 0``
    gives 0.  Where the ends do not bracket a zero the result is 1 if no
    sample changed sign (round-off at the step end).

    Returns a float for numbers, an array for arrays.
    """
    if all(isinstance(a, (int, float)) for a in (g0, g1, d0, d1)):
        return _first_root_of_one(float(g0), float(g1), float(d0), float(d1))
    g0, g1, d0, d1 = np.broadcast_arrays(*(np.asarray(a, dtype=float) for a in (g0, g1, d0, d1)))
    scalar = g0.ndim == 0
    g0, g1, d0, d1 = (np.atleast_1d(a).astype(float) for a in (g0, g1, d0, d1))
    if g0.size <= _FEW:                     # a few roots: one by one, the same steps without numpy's per-call cost
        root = np.array([_first_root_of_one(*map(float, a)) for a in zip(g0.flat, g1.flat, d0.flat, d1.flat)])
        root = root.reshape(g0.shape)
        return float(root[0]) if scalar else root
    left, right = np.zeros_like(g0), np.ones_like(g0)
    found = g0 == 0.0
    root = np.where(found, 0.0, 1.0)
    pending = np.zeros_like(found)          # a sign change was bracketed: refine it
    before = g0.copy()
    for k in range(1, SAMPLES + 1):
        u = k / SAMPLES
        after = values(u, g0, g1, d0, d1) if k < SAMPLES else g1
        exact = ~found & (after == 0.0)
        root[exact] = u
        crossing = ~found & ~exact & ((after > 0.0) != (before > 0.0))
        left[crossing], right[crossing] = (k - 1) / SAMPLES, u
        pending |= crossing
        found |= exact | crossing
        before = after
    positive_left = values(left, g0, g1, d0, d1) > 0.0
    u = 0.5 * (left + right)
    active = pending.copy()
    for iteration in range(_MAX_ITERATIONS):
        remaining = np.flatnonzero(active)
        if remaining.size <= _FEW:          # the last few (bisection's long tails): one by one, the same steps
            for j in remaining:
                root.flat[j] = _refine_one(float(g0.flat[j]), float(g1.flat[j]), float(d0.flat[j]),
                                           float(d1.flat[j]), float(u.flat[j]), float(left.flat[j]),
                                           float(right.flat[j]), bool(positive_left.flat[j]),
                                           _MAX_ITERATIONS - iteration)
            active[...] = False
            break
        value = values(u, g0, g1, d0, d1)
        hit = active & (value == 0.0)
        root[hit] = u[hit]
        active &= ~hit
        to_left = (value > 0.0) == positive_left
        left = np.where(active & to_left, u, left)
        right = np.where(active & ~to_left, u, right)
        slope = slopes(u, g0, g1, d0, d1)
        newton = u - value / np.where(slope != 0.0, slope, 1.0)
        u_next = np.where((slope != 0.0) & (newton > left) & (newton < right), newton, 0.5 * (left + right))
        done = active & ((np.abs(u_next - u) <= ROOT_TOLERANCE) | (right - left <= ROOT_TOLERANCE))
        root[done] = u_next[done]
        active &= ~done
        u = np.where(active, u_next, u)
    root[active] = u[active]
    return float(root[0]) if scalar else root


def _first_root_of_one(g0, g1, d0, d1):
    """:func:`first_root` for four Python floats, the same steps without arrays (the compiled
    DOP853 locates one event at a time, where numpy's per-call cost would dominate)."""
    if g0 == 0.0:
        return 0.0
    left, before = 0.0, g0
    for k in range(1, SAMPLES + 1):
        right = k / SAMPLES
        after = values(right, g0, g1, d0, d1) if k < SAMPLES else g1
        if after == 0.0:
            return right
        if (after > 0.0) != (before > 0.0):
            break
        left, before = right, after
    else:
        return 1.0
    positive_left = values(left, g0, g1, d0, d1) > 0.0
    return _refine_one(g0, g1, d0, d1, 0.5 * (left + right), left, right, positive_left, _MAX_ITERATIONS)


def _refine_one(g0, g1, d0, d1, u, left, right, positive_left, iterations):
    """Safeguarded Newton from ``u`` in the bracket ``[left, right]``, at most ``iterations`` steps:
    the refinement of :func:`first_root` for one root on Python floats (the arrays' loop hands its
    last few roots over to it, with their state, so they get the very same steps)."""
    for _ in range(iterations):
        value = values(u, g0, g1, d0, d1)
        if value == 0.0:
            return u
        if (value > 0.0) == positive_left:
            left = u
        else:
            right = u
        slope = slopes(u, g0, g1, d0, d1)
        newton = u - value / slope if slope != 0.0 else left - 1.0
        u_next = newton if left < newton < right else 0.5 * (left + right)
        if abs(u_next - u) <= ROOT_TOLERANCE or right - left <= ROOT_TOLERANCE:
            return u_next
        u = u_next
    return u


def turning_point(g0, g1, d0, d1):
    """Where the interpolant turns (dp/du = 0) in a step whose end slopes d0, d1 differ in sign.

    dp/du is a quadratic with the values d0, d1 at the ends, so it has one
    zero there; it is found as the first root of dp/du written in Hermite
    form (its own slopes are d2p/du2 at the ends).
    """
    change = np.asarray(g1, dtype=float) - np.asarray(g0, dtype=float)
    curvature0 = 6.0 * change - 4.0 * np.asarray(d0, dtype=float) - 2.0 * np.asarray(d1, dtype=float)
    curvature1 = -6.0 * change + 2.0 * np.asarray(d0, dtype=float) + 4.0 * np.asarray(d1, dtype=float)
    return first_root(d0, d1, curvature0, curvature1)
