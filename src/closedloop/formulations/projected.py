"""The projection method: integrate (12), then put every step back on the constraint manifold.

The augmented system (12) keeps f'' = 0 (14) but lets f and f' drift (13).
Baumgarte (15) feeds the drift back into the equations; the projection method
instead leaves the equations alone and corrects the *state*: after each
accepted step of the integrator,

- the positions are moved onto f(s) = 0 (6) by Newton's method with the
  minimum-norm correction ``s <- s - Phi_s^T (Phi_s Phi_s^T)^{-1} f(s)``;
- the velocities are moved onto f' = Phi_s s' = 0 (9) by the orthogonal
  projection ``s' <- s' - Phi_s^T (Phi_s Phi_s^T)^{-1} Phi_s s'``,

and the integration continues from the corrected state.

Only the explicit Runge-Kutta methods of solve_ivp (RK23, RK45, DOP853) can be
corrected this way: their whole memory is the current state and its derivative,
so both can be reset after a step.  BDF keeps a history of past states, Radau
its last collocation polynomial, and LSODA lives in Fortran; none of them can
be reset from Python, so :class:`Projected` refuses them.

The dense output between two steps (used for ``t_eval`` and to locate the
switches of the gas force) is the method's own interpolant, projected the same
way at every point where it is evaluated.  So every state that
:func:`closedloop.simulate` reports, and every state at which a switch is
decided, satisfies f = 0 and f' = 0 to Newton's tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConvergenceError, InputError, SingularConfigurationError, at_time
from ..kinematics import NEWTON_MAX_ITERATIONS, NEWTON_TOLERANCE, newton_on_constraints
from ..linalg import solve_small
from ..methods import EXPLICIT_RUNGE_KUTTA_METHODS, solver_classes
from .redundant import Augmented

__all__ = ["Projected", "project_state", "PROJECTABLE_METHODS"]


def __getattr__(name):
    """``PROJECTABLE_METHODS``: the solve_ivp methods whose state can be reset after a step, ``{name: class}``
    (made on first use, so that importing this module does not import scipy.integrate)."""
    if name == "PROJECTABLE_METHODS":
        classes = solver_classes()
        methods = globals()["PROJECTABLE_METHODS"] = {name: classes[name] for name in EXPLICIT_RUNGE_KUTTA_METHODS}
        return methods
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _minimum_norm(Phi, residual, t, s):
    """``Phi^T (Phi Phi^T)^{-1} residual``: the shortest ``d`` with ``Phi d = residual``."""
    try:
        return Phi.T @ solve_small(Phi @ Phi.T, residual)
    except np.linalg.LinAlgError:
        where = ", ".join(f"{value:.6g}" for value in s)
        raise SingularConfigurationError(
            f"Phi_s Phi_s^T is singular{at_time(t)} (s = ({where})): the constraints are dependent, Phi_s "
            "has lost rank (a change point, where assembly branches meet), so the projection onto f = 0 is "
            "not defined there; no formulation of this library passes a change point"
        ) from None


def project_state(system, s, sd, t=None, tolerance=NEWTON_TOLERANCE, max_iterations=NEWTON_MAX_ITERATIONS):
    """A state near ``(s, s')`` that satisfies f = 0 (6) and f' = 0 (9).

    Near, not the nearest: each Newton step is the minimum-norm correction of
    the linearised f, so the sum of the steps is close to, but not exactly, the
    orthogonal projection onto f = 0 (they differ at second order in the
    distance).  The velocities are the exact orthogonal projection.

    Positions: Newton's method on f(s) = 0 with the minimum-norm correction
    ``Delta s = -Phi_s^T (Phi_s Phi_s^T)^{-1} f(s)`` at every iteration (the
    shortest step, in the Euclidean norm of s, that zeroes the linearised f).
    Velocities: the orthogonal projection of s' onto the null space of Phi_s
    at the corrected positions, ``s' - Phi_s^T (Phi_s Phi_s^T)^{-1} Phi_s s'``.

    Parameters
    ----------
    system : System
    s, sd : ndarray, shape (n,)
        Coordinates and velocities, close to the constraint manifold.
    t : float, optional
        Time, only to make error messages precise.
    tolerance : float, optional
        Newton stops when ``max |f| <= tolerance (1 + max |s|)``, as
        :func:`closedloop.kinematics.solve_dependent`.
    max_iterations : int, optional

    Returns
    -------
    s, sd : ndarray, shape (n,)
        New arrays; the inputs are not changed.

    Raises
    ------
    ConvergenceError
        If Newton does not reach the tolerance (the state is too far from the manifold).
    SingularConfigurationError
        If Phi_s loses rank on the way.
    """
    try:
        s, sd = np.array(s, dtype=float), np.array(sd, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"s, sd: expected {system.n} numbers each, got {type(s).__name__} and "
                         f"{type(sd).__name__}") from None
    if s.shape != (system.n,) or sd.shape != (system.n,):
        raise InputError(f"s, sd: expected {system.n} numbers each, got shapes {s.shape} and {sd.shape}")

    def correct(s, constraint_values, Phi):          # s <- s - Phi^T (Phi Phi^T)^{-1} f: no step test
        s -= _minimum_norm(Phi, constraint_values, t, s)

    solution = newton_on_constraints(system.constraints_and_jacobian, correct, s, tolerance, max_iterations)
    if solution is not None:
        s, Phi = solution
        sd = np.asarray(sd, dtype=float)
        return s, sd - _minimum_norm(Phi, Phi @ sd, t, s)
    residual = np.linalg.norm(system.constraints(s)) if np.all(np.isfinite(s)) else np.inf
    if residual <= 1e3 * np.finfo(float).eps * (1.0 + np.max(np.abs(s))):     # close, but not to `tolerance`
        raise ConvergenceError(
            f"the projection onto f = 0 stalled at |f| = {residual:.3g}{at_time(t)}, as close as floating "
            f"point gets here, above the tolerance {tolerance:.3g} (1 + max |s|); call project_state with a "
            f"larger tolerance, e.g. {10 * residual / (1.0 + np.max(np.abs(s))):.0e}")
    raise ConvergenceError(
        f"the projection onto f = 0 did not converge in {max_iterations} Newton iterations{at_time(t)} "
        f"(|f| = {residual:.3g}): the integrator left the constraint manifold too far; "
        "tighten rtol and atol"
    )


class _ProjectedDenseOutput:
    """A step's interpolant whose every value is projected onto f = 0, f' = 0."""

    def __init__(self, interpolant, project):
        self.interpolant, self.project = interpolant, project
        self.t_old, self.t = interpolant.t_old, interpolant.t

    def __call__(self, t):
        y = np.asarray(self.interpolant(t), dtype=float)
        if y.ndim == 1:
            return self.project(t, y)
        times = np.broadcast_to(np.asarray(t, dtype=float), (y.shape[1],))
        return np.column_stack([self.project(times[k], y[:, k]) for k in range(y.shape[1])])


def _projecting_solver(base, system):
    """A subclass of the Runge-Kutta solver ``base`` that projects its state after each step."""
    n = system.n

    def project(t, y):
        s, sd = project_state(system, y[:n], y[n:2 * n], t)
        return np.concatenate((s, sd, y[2 * n:]))          # rule 9 of the contract: the runner's entries kept

    class ProjectingSolver(base):
        __doc__ = f"{base.__name__}, with the state projected onto f = 0, f' = 0 after every step."

        def _step_impl(self):
            success, message = super()._step_impl()
            if success:
                self.y = project(self.t, self.y)
                self.f = self.fun(self.t, self.y)      # the next step starts from f at the new y
            return success, message

        def _dense_output_impl(self):
            return _ProjectedDenseOutput(super()._dense_output_impl(), project)

    ProjectingSolver.__name__ = f"Projected{base.__name__}"
    return ProjectingSolver


@dataclass(frozen=True)
class Projected(Augmented):
    """The augmented system (12), with the state projected onto f = 0 and f' = 0 after every step.

    The equations are those of :class:`~closedloop.formulations.Augmented`
    (no stabilisation); the drift (13) is removed by :func:`project_state`
    after each accepted step of an explicit Runge-Kutta method.  Only the
    methods in :data:`PROJECTABLE_METHODS` (RK23, RK45, DOP853) can be used;
    :func:`closedloop.simulate` refuses the others with an InputError.

    Each step costs one right-hand-side evaluation more than with Augmented
    (the derivative at the projected state), counted in ``nfev``.
    """

    name = "projected"

    def check_method(self, method):
        """Raise InputError unless ``method`` names a method whose state can be reset."""
        if not (isinstance(method, str) and method in EXPLICIT_RUNGE_KUTTA_METHODS):
            shown = method if isinstance(method, str) else getattr(method, "__name__", repr(method))
            raise InputError(
                f"method: the projected formulation needs an explicit Runge-Kutta method of solve_ivp, whose "
                f"state it resets after each step ({', '.join(EXPLICIT_RUNGE_KUTTA_METHODS)}), got {shown!r}"
            )

    def integrator(self, system, method):
        """The OdeSolver class that solve_ivp runs: ``method`` with a projection after each step."""
        self.check_method(method)
        return _projecting_solver(solver_classes()[method], system)
