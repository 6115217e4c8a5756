"""Position and velocity level kinematics: dependent coordinates from independent ones.

Used for consistent initial conditions (the paper's remark after (26)) and by the
minimal-coordinate formulation, which solves ``f(q, z) = 0`` for ``z`` at every
evaluation.
"""

from __future__ import annotations

import numpy as np

from .errors import ConvergenceError, SingularConfigurationError, at_time
from .linalg import orthogonal_complement, solve_small
from .validation import finite_array

__all__ = ["solve_dependent", "dependent_velocities", "consistent_initial_state", "InitialState"]

#: Newton stops when |f| (or its step) is below this, relative to 1 + |s| (or 1 + |z|).
NEWTON_TOLERANCE = 1e-15
NEWTON_MAX_ITERATIONS = 25


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
    f_tolerance = tolerance * (1.0 + np.abs(s).max())
    for _ in range(max_iterations):
        f, Phi = system.constraints_and_jacobian(s)
        if np.abs(f).max() <= f_tolerance:
            return (s, Phi) if return_jacobian else s
        Phi_z = Phi[:, zi]
        try:
            step = solve_small(Phi_z, f)
        except np.linalg.LinAlgError:
            raise SingularConfigurationError(
                f"Phi_z is singular{at_time(t)} at s = {np.array2string(s, precision=6)}: "
                "the dependent coordinates are not determined there (a kinematic singularity); "
                "start from another guess of z or choose other independent coordinates"
            ) from None
        s[zi] -= step
        if not np.all(np.isfinite(s)):
            break
        if np.abs(step).max() <= tolerance * (1.0 + np.abs(s[zi]).max()):
            return (s, system.jacobian(s)) if return_jacobian else s
    residual = np.linalg.norm(system.constraints(s)) if np.all(np.isfinite(s)) else np.inf
    raise ConvergenceError(
        f"Newton on f(q, z) = 0 did not converge in {max_iterations} iterations{at_time(t)} "
        f"(q = {np.array2string(np.asarray(q), precision=6)}, |f| = {residual:.3g}): the mechanism "
        "may not assemble at this q, or the guess of z is on no branch"
    )


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
        self.s = np.asarray(s, dtype=float)
        self.sd = np.asarray(sd, dtype=float)

    def __repr__(self):
        return f"InitialState(s={self.s!r}, sd={self.sd!r})"


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
    """
    q0 = finite_array("q0", q0, size=system.f)
    qd0 = finite_array("qd0", qd0, size=system.f)
    z_guess = finite_array("z_guess", z_guess, size=system.r)
    s = solve_dependent(system, q0, z_guess)
    return InitialState(s, dependent_velocities(system, s, qd0))
