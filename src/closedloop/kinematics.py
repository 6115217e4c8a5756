"""Position and velocity level kinematics: dependent coordinates from independent ones.

Used for consistent initial conditions (the paper's remark after (26)) and by the
minimal-coordinate formulation, which solves ``f(q, z) = 0`` for ``z`` at every
evaluation.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import ConvergenceError, InputError, SingularConfigurationError, at_time
from .linalg import RANK_LIMIT, orthogonal_complement, solve_many, solve_small
from .validation import finite_array, shown

__all__ = ["solve_dependent", "solve_dependent_many", "dependent_constraints_error", "newton_on_constraints", "dependent_velocities",
           "consistent_initial_state", "InitialState", "NEWTON_TOLERANCE", "NEWTON_MAX_ITERATIONS"]

#: Newton stops when |f| (or its step) is below this, relative to 1 + |s| (or 1 + |z|).
NEWTON_TOLERANCE = 1e-15
#: Newton iterations after which the dependent coordinates count as not found.
NEWTON_MAX_ITERATIONS = 25


def newton_on_constraints(evaluate, correct, s, tolerance=NEWTON_TOLERANCE, max_iterations=NEWTON_MAX_ITERATIONS):
    """Newton's method on the constraints f(s) = 0 (6), for one state or for K states at once.

    The one Newton loop of the library: :func:`solve_dependent` (z from q),
    :func:`solve_dependent_many` (the same for a batch) and
    :func:`closedloop.formulations.project_state` (the minimum-norm correction
    of all coordinates) differ only in ``evaluate`` and ``correct``.

    Parameters
    ----------
    evaluate : callable
        ``evaluate(s) -> (f, Phi_s)`` of (6) and (9).
    correct : callable
        ``correct(s, f, Phi) -> step``: changes ``s`` in place by one Newton
        correction and returns ``(moved, entries)``, the step of the corrected
        entries and their new values (for the step test), or None when only the
        residual test applies.
    s : ndarray, shape (n,) or (n, K)
        The starting state(s); changed in place.  With K columns every
        reduction runs down the columns and all of them must pass.
    tolerance : float
        Newton stops when ``max |f| <= tolerance (1 + max |s|)`` (the smaller
        |s| of the start and of the iterate: a guess far off, 4.5e15 say, does
        not make |f| = 0.5 small), or when a step is below
        ``tolerance (1 + max |entries|)``.
    max_iterations : int

    Returns
    -------
    (s, Phi) : tuple of ndarray, or None
        The converged state and Phi_s there, or None if Newton did not converge
        (or left the finite numbers): the caller names the failure.
    """
    if s.ndim == 1:
        return _newton_one_state(evaluate, correct, s, tolerance, max_iterations)
    f_tolerance = tolerance * (1.0 + np.abs(s).max(axis=0))
    for _ in range(max_iterations):
        f, Phi = evaluate(s)
        if np.all(np.abs(f).max(axis=0) <= np.minimum(f_tolerance, tolerance * (1.0 + np.abs(s).max(axis=0)))):
            return s, Phi
        step = correct(s, f, Phi)
        if not np.all(np.isfinite(s)):
            break
        if step is not None:
            moved, entries = step
            if np.all(np.abs(moved).max(axis=0) <= tolerance * (1.0 + np.abs(entries).max(axis=0))):
                return s, evaluate(s)[1]
    return None


def _largest_magnitude(values):
    """``max |v|`` of a short 1-d array, as numpy's ``np.abs(v).max()`` gives it (NaN if any is NaN)."""
    listed = np.ravel(values).tolist()
    if not listed:
        return np.abs(values).max()         # raises as numpy does for no values
    largest = 0.0
    for value in listed:
        value = abs(value)
        if value != value:                  # a NaN wins, as in numpy's max
            return value
        if value > largest:
            largest = value
    return largest


def _newton_one_state(evaluate, correct, s, tolerance, max_iterations):
    """:func:`newton_on_constraints` for one state: the same tests on Python floats.

    A right-hand side of the minimal formulation runs Newton on a few numbers at
    every evaluation; numpy's reductions cost more than the arithmetic there.
    ``max`` and ``abs`` are exact, so every test decides as the array version does.
    """
    f_tolerance = tolerance * (1.0 + _largest_magnitude(s))
    for _ in range(max_iterations):
        f, Phi = evaluate(s)
        residual = _largest_magnitude(f)
        if residual <= f_tolerance and residual <= tolerance * (1.0 + _largest_magnitude(s)):
            return s, Phi
        step = correct(s, f, Phi)
        if not all(map(math.isfinite, s.tolist())):
            break
        if step is not None:
            moved, entries = step
            if _largest_magnitude(moved) <= tolerance * (1.0 + _largest_magnitude(entries)):
                return s, evaluate(s)[1]
    return None


def solve_dependent(system, q, z_guess, t=None, tolerance=NEWTON_TOLERANCE,
                    max_iterations=NEWTON_MAX_ITERATIONS, return_jacobian=False):
    """Solve the constraints ``f(q, z) = 0`` (6) for ``z`` by Newton's method.

    Parameters
    ----------
    system : System
    q : ndarray, shape (f,)
        Independent coordinates.
    z_guess : ndarray, shape (r,)
        Starting guess; it selects the assembly branch (for the slider-crank,
        psi near pi puts the slider to the right of the crank).
    t : float, optional
        Time, only to make error messages precise.
    tolerance : float, optional
        Newton stops when ``max |f| <= tolerance (1 + max |s|)`` or when its
        step is below ``tolerance (1 + max |z|)``.
    return_jacobian : bool, optional
        Also return Phi_s at the solution (it is computed on the way).

    Returns
    -------
    s : ndarray, shape (n,)
        The full coordinate vector with ``s[q_index] = q`` and ``s[z_index] = z``.
    Phi : ndarray, shape (r, n)
        Only with ``return_jacobian``.

    Raises
    ------
    ConvergenceError
        If Newton does not converge (no assembly exists, or the guess is poor).
    SingularConfigurationError
        If Phi_z is singular on the way.
    """
    s = np.empty(system.n)
    s[system.q_index] = q
    s[system.z_index] = z_guess
    zi = system.z_index

    def correct(s, f, Phi):                   # z <- z - Phi_z^{-1} f
        try:
            step = solve_small(Phi[:, zi], f)
        except np.linalg.LinAlgError:
            raise dependent_constraints_error(Phi, s, t) or SingularConfigurationError(
                f"Phi_z is singular{at_time(t)} at s = {np.array2string(s, precision=6)}: "
                "the dependent coordinates are not determined there (a kinematic singularity); "
                "start from another guess of z or choose other independent coordinates"
            ) from None
        s[zi] -= step
        return step, s[zi]

    solution = newton_on_constraints(system.constraints_and_jacobian, correct, s, tolerance, max_iterations)
    if solution is not None:
        return solution if return_jacobian else solution[0]
    residual = np.linalg.norm(system.constraints(s)) if np.all(np.isfinite(s)) else np.inf
    raise ConvergenceError(
        f"Newton on f(q, z) = 0 did not converge in {max_iterations} iterations{at_time(t)} "
        f"(q = {np.array2string(np.asarray(q), precision=6)}, |f| = {residual:.3g}): the mechanism "
        "may not assemble at this q, or the guess of z is on no branch"
    )


def dependent_constraints_error(Phi, s, t=None):
    """The SingularConfigurationError for constraints whose Jacobian Phi_s (r x n) loses rank at ``s``, or None.

    A Phi_z that is singular because the rows of Phi_s themselves are dependent is no dead position of
    the independent coordinates: no guess of z and no other partition helps.
    """
    singular_values = np.linalg.svd(np.asarray(Phi, dtype=float), compute_uv=False)
    if not (np.all(np.isfinite(singular_values)) and singular_values[0] > 0):
        return None
    if singular_values[-1] > RANK_LIMIT * singular_values[0]:
        return None
    rank = int(np.sum(singular_values > RANK_LIMIT * singular_values[0]))
    return SingularConfigurationError(
        f"the constraints are not independent{at_time(t)} at s = {np.array2string(np.asarray(s), precision=6)}: "
        f"Phi_s has rank {rank} < r = {singular_values.size} there, so f = 0 does not fix the dependent "
        "coordinates; remove a constraint that repeats the others, or, at a change point of the mechanism, "
        "start away from it"
    )


def solve_dependent_many(system, q, z_guess, tolerance=NEWTON_TOLERANCE, max_iterations=NEWTON_MAX_ITERATIONS):
    """:func:`solve_dependent` at K states at once: ``f(q_j, z_j) = 0`` (6) for every column j.

    Parameters
    ----------
    system : System
    q : ndarray, shape (f, K) (or (K,) when f = 1)
    z_guess : ndarray, shape (r, K)

    Returns
    -------
    s : ndarray, shape (n, K)
    Phi : ndarray, shape (r, n, K)
        Phi_s of (9) at the solutions.

    Raises
    ------
    ConvergenceError
        If Newton does not converge at every column.
    SingularConfigurationError
        If Phi_z is singular at some column on the way.
    """
    zi = system.z_index
    s = np.empty((system.n, np.shape(z_guess)[-1]))
    s[system.q_index] = q
    s[zi] = z_guess

    def correct(s, f, Phi):
        step = solve_many(Phi[:, zi], f)
        s[zi] -= step
        return step, s[zi]

    solution = newton_on_constraints(system.constraints_and_jacobian_many, correct, s, tolerance, max_iterations)
    if solution is None:
        raise ConvergenceError(
            f"Newton on f(q, z) = 0 did not converge in {max_iterations} iterations for some "
            "cells of the batch: the mechanism may not assemble there"
        )
    return solution


def dependent_velocities(system, s, qd, t=None):
    """Velocities ``s'`` with ``z' = -Phi_z^{-1} Phi_q q'`` from (9), i.e. ``s' = R q'`` (20)."""

    R = orthogonal_complement(system.jacobian(s), system.q_index, system.z_index, t)
    return R @ np.asarray(qd, dtype=float)


class InitialState:
    """Consistent initial values ``(s0, s0')``: they satisfy f = 0 and f' = 0.

    Attributes
    ----------
    s, sd : ndarray, shape (n,)
    """

    def __init__(self, s, sd):
        self.s = _numbers("s", s)
        self.sd = _numbers("sd", sd)

    def __repr__(self):
        return f"InitialState(s={self.s!r}, sd={self.sd!r})"


def _numbers(name, values):
    """``values`` as a flat float array, or an InputError naming InitialState's ``name`` (finiteness and size are
    checked later, by :func:`initial_state_arrays`, against the system)."""
    if values is None or isinstance(values, (str, bytes)):
        raise InputError(f"InitialState: {name} must be numbers, got {shown(values)}")
    try:
        array = np.asarray(values, dtype=float)
    except (TypeError, ValueError, OverflowError):
        raise InputError(f"InitialState: {name} must be numbers, got {shown(values)}") from None
    if array.ndim != 1:
        raise InputError(f"InitialState: {name} must be a flat list of numbers, got {shown(values)}")
    return array


def initial_state_arrays(initial_state, n):
    """``(s0, s0')`` of an :class:`InitialState` of ``n`` finite coordinates and velocities, or a clear error.

    Raises
    ------
    InputError
        Naming ``initial_state``: not an InitialState, another size, or not finite.
    """
    if not isinstance(initial_state, InitialState):
        raise InputError("initial_state: expected an InitialState (see consistent_initial_state)")
    s0, sd0 = initial_state.s, initial_state.sd
    if s0.shape != (n,) or sd0.shape != (n,):
        raise InputError(f"initial_state: need {n} coordinates and {n} velocities")
    if not (np.isfinite(s0).all() and np.isfinite(sd0).all()):
        raise InputError("initial_state: coordinates and velocities must be finite")
    return s0, sd0


def consistent_initial_state(system, q0, qd0, z_guess):
    """Consistent initial conditions from ``q(0)``, ``q'(0)`` and a guess of ``z(0)``.

    Newton on f = 0 (6) for z, then ``Phi_z z' = -Phi_q q'`` from (9).

    Parameters
    ----------
    system : System
    q0, qd0 : array_like, shape (f,)
    z_guess : array_like, shape (r,)
        Selects the assembly branch.

    Returns
    -------
    InitialState

    Raises
    ------
    SingularConfigurationError
        Where Phi_z is singular on Newton's way from the guess, or at the solution (a dead
        position of q, where q' does not fix z').
    InputError
        Where an argument is of the wrong kind, size or not finite, or where the velocities
        R q'(0) overflow float64.
    """
    from .model import System

    if not isinstance(system, System):
        raise InputError(f"system: expected a System, got {type(system).__name__}")
    q0 = finite_array("q0", q0, size=system.f)
    qd0 = finite_array("qd0", qd0, size=system.f)
    z_guess = finite_array("z_guess", z_guess, size=system.r)
    s = solve_dependent(system, q0, z_guess)       # its own error names a singular guess
    try:
        with np.errstate(over="ignore", invalid="ignore"):
            sd = dependent_velocities(system, s, qd0)
    except SingularConfigurationError:
        dependent = dependent_constraints_error(system.jacobian(s), s)
        if dependent is not None:
            raise dependent from None
        raise SingularConfigurationError(
            f"q0: Phi_z is singular at q0 = {q0.tolist()} (a dead position of the independent coordinates), so "
            "q'(0) does not fix z'(0) through (9); start away from it, or give InitialState(s0, s0') with "
            "Phi_s s0' = 0 yourself (any formulation that needs no partition, NullSpace, can run from it)"
        ) from None
    if not np.all(np.isfinite(sd)):
        raise InputError(f"qd0: the velocities s' = R q'(0) of (20) overflow float64 at s = {s.tolist()}, "
                         f"got qd0 = {qd0.tolist()}; give smaller velocities")
    return InitialState(s, sd)
