"""A fixed-step classical Runge-Kutta scheme, and its stability with Baumgarte's (15).

For the lesson on stiffness: with a fixed step dt there is no error control to
hide an instability, so the step at which Baumgarte's feedback (15) makes the
integration blow up can be mapped, and compared with linear stability theory.

Each component e of the constraint error obeys (15), ``e'' + 2 alpha e' + beta^2 e = 0``,
a linear ODE with the characteristic roots ``mu = -alpha +/- sqrt(alpha^2 - beta^2)``.
The classical Runge-Kutta scheme (RK4) multiplies each mode by the stability
function ``R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24`` per step, ``z = mu dt``, so the
error is damped by the integration only if ``|R(mu dt)| <= 1`` for both roots.
The roots scale with the step: ``mu dt`` depends on ``(alpha dt, beta dt)`` alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .errors import InputError, IntegrationError
from .formulations import Baumgarte, Formulation
from .model import System
from .validation import instance_of, positive_integer, positive_number

__all__ = [
    "rk4_step",
    "rk4",
    "FixedStepResult",
    "rk4_stability_function",
    "baumgarte_roots",
    "rk4_baumgarte_growth",
    "rk4_baumgarte_stable",
    "rk4_real_axis_limit",
    "rk4_stability_map",
    "MIN_START_ERROR",
]

#: The smallest |f(s0)| [m] that :func:`rk4_stability_map` starts from: far above the round-off of |f|
#: (about 1e-15 m here), so that the growth it returns is that of the error equation (15).
MIN_START_ERROR = 1e-9


def rk4_step(slope, t, y, step, k1=None):
    """One step of the classical Runge-Kutta scheme: ``y(t + step)`` of ``y' = slope(t, y)``.

    The library's one RK4 step: :func:`rk4`, the stability map's batch, the switching
    rule's probe and the batch integrator all take it.

    Parameters
    ----------
    slope : callable
        ``slope(t, y)``, an array of the shape of ``y``.
    t : float or ndarray
        Time at the start [s] (one per column of ``y`` for a batch).
    y : ndarray
        State at the start, one state or one per column.
    step : float or ndarray
        Step [s] (one per column for a batch).
    k1 : ndarray, optional
        ``slope(t, y)`` when the caller has it already.

    Returns
    -------
    ndarray
        The state after the step, ``y + step/6 (k1 + 2 k2 + 2 k3 + k4)``.
    """
    if k1 is None:
        k1 = slope(t, y)
    k2 = slope(t + step / 2, y + step / 2 * k1)
    k3 = slope(t + step / 2, y + step / 2 * k2)
    k4 = slope(t + step, y + step * k3)
    return y + step / 6 * (k1 + 2 * k2 + 2 * k3 + k4)


def rk4_stability_function(z):
    """``R(z) = 1 + z + z^2/2 + z^3/6 + z^4/24``: one RK4 step of ``y' = mu y`` is ``y -> R(mu dt) y``."""
    z = np.asarray(z, dtype=complex)
    return 1.0 + z * (1.0 + z * (0.5 + z * (1.0 / 6.0 + z / 24.0)))


def baumgarte_roots(alpha, beta):
    """The roots ``mu_1,2 = -alpha +/- sqrt(alpha^2 - beta^2)`` of (15)'s characteristic equation.

    Parameters
    ----------
    alpha, beta : float or ndarray
        Gains (or gains times a step: the roots scale with them).

    Returns
    -------
    mu1, mu2 : complex ndarray
    """
    alpha = np.asarray(alpha, dtype=float)
    beta = np.asarray(beta, dtype=float)
    root = np.sqrt((alpha * alpha - beta * beta).astype(complex))
    return -alpha + root, -alpha - root


def rk4_baumgarte_growth(alpha_step, beta_step):
    """The larger ``|R(mu dt)|`` of the two roots of (15): the error's growth per RK4 step.

    Parameters
    ----------
    alpha_step, beta_step : float or ndarray
        ``alpha dt`` and ``beta dt`` (broadcast together).
    """
    mu1, mu2 = baumgarte_roots(alpha_step, beta_step)
    return np.maximum(np.abs(rk4_stability_function(mu1)), np.abs(rk4_stability_function(mu2)))


def rk4_baumgarte_stable(alpha_step, beta_step):
    """Linear theory: RK4 keeps (15) stable iff ``|R(mu dt)| <= 1`` for both roots.

    A tiny allowance (1e-12) keeps the marginal point ``alpha = beta = 0`` (R = 1) stable.
    """
    return rk4_baumgarte_growth(alpha_step, beta_step) <= 1.0 + 1e-12


def rk4_real_axis_limit():
    """The left end of RK4's stability interval on the negative real axis: ``|R(-x)| = 1`` at x = 2.785...

    With ``beta = 0`` the fast root of (15) is ``mu = -2 alpha``, so RK4 is stable
    for ``alpha dt`` up to half this value.
    """
    from scipy.optimize import brentq     # here only: importing scipy.optimize costs about 0.1 s

    return brentq(lambda x: abs(rk4_stability_function(-x)) - 1.0, 2.0, 3.0, xtol=1e-14)


@dataclass
class FixedStepResult:
    """What :func:`rk4` computed.

    Attributes
    ----------
    t : ndarray, shape (N,)
        The step times, ``t_start + k dt``, up to where the run ended.
    s, sd : ndarray, shape (n, N)
    constraint_error : ndarray, shape (N,)
        ``|f|`` of (32) at each step.
    step : float
    diverged_at : float or None
        The time at which ``|f|`` first exceeded ``divergence`` times its
        starting value (or the state stopped being finite); the run ends there.
    """

    t: np.ndarray
    s: np.ndarray
    sd: np.ndarray
    constraint_error: np.ndarray
    step: float
    diverged_at: float | None = None

    @property
    def growth(self) -> float:
        """``|f|`` at the end over ``|f|`` at the start."""
        return float(self.constraint_error[-1] / self.constraint_error[0])


def rk4(system, formulation, s0, sd0, step, n_steps, t_start=0.0, divergence=1e6):
    """Integrate with the classical Runge-Kutta scheme at a fixed step ``dt``.

    The state need not be consistent: starting off the constraints is how
    the decay (or growth) of the error under (15) is observed.

    Parameters
    ----------
    system : System
        Without switched forces (this scheme does not stop at switches).
    formulation : Formulation
        Any of the library's (:func:`closedloop.formulations.formulation_from_name`) that runs
        with any method: :class:`~closedloop.formulations.Projected` projects inside solve_ivp's
        steps, which this scheme does not take, and is refused (its ``check_method``).
    s0, sd0 : array_like, shape (n,)
    step : float
        dt > 0 [s].
    n_steps : int
        Number of steps, >= 1.
    t_start : float, optional
    divergence : float, optional
        The run stops when ``|f|`` exceeds ``divergence * max(|f(0)|, 1e-12)``.

    Returns
    -------
    FixedStepResult

    Raises
    ------
    InputError
        For a system with switched forces, a formulation that cannot run this scheme, a step <= 0,
        or n_steps < 1.
    IntegrationError
        If the right-hand side overflows before the divergence test catches it.
    """
    instance_of("system", system, System)
    if not isinstance(formulation, Formulation):
        raise InputError(f"formulation: expected a Formulation, got {type(formulation).__name__}")
    if system.force is not None and system.force.switch_names:
        raise InputError("system: rk4 does not stop at switches; use a system without switched forces "
                         "(e.g. slider_crank_system(gas=False)) or simulate()")
    try:
        formulation.check_method("rk4")
    except InputError as error:
        raise InputError(f"formulation: {type(formulation).__name__} cannot run this fixed-step scheme ({error}); "
                         "use simulate()") from None
    positive_number("step", step, unit="s")
    positive_integer("n_steps", n_steps)
    s0 = np.asarray(s0, dtype=float)
    sd0 = np.asarray(sd0, dtype=float)
    unpack = formulation.unpacker(system)
    unpack.seed(s0)
    mode = system.force.mode_at(t_start, s0, sd0) if system.force is not None else ()
    formulation_rhs = formulation.make_rhs(system, mode, unpack)

    def rhs(t, y):                      # ClosedForm's generated code returns a list (ode.dop853 takes it)
        return np.asarray(formulation_rhs(t, y), dtype=float)

    y = np.asarray(formulation.pack(system, s0, sd0), dtype=float)
    limit = divergence * max(np.linalg.norm(system.constraints(s0)), 1e-12)
    times, states, errors = [t_start], [(s0, sd0)], [np.linalg.norm(system.constraints(s0))]
    diverged_at = None
    t = t_start
    for k in range(n_steps):
        try:
            y = rk4_step(rhs, t, y, step)
        except (OverflowError, FloatingPointError) as error:
            raise IntegrationError(f"rk4: the right-hand side overflowed at t = {t:.6g} s ({error}) "
                                   f"with dt = {step:.3g} s; take a smaller step") from None
        t = t_start + (k + 1) * step
        if not np.all(np.isfinite(y)):
            diverged_at = t
            break
        s, sd = unpack(y, t)
        error = np.linalg.norm(system.constraints(s))
        times.append(t)
        states.append((s, sd))
        errors.append(error)
        if not error <= limit:
            diverged_at = t
            break
    return FixedStepResult(
        t=np.array(times), s=np.array([p[0] for p in states]).T, sd=np.array([p[1] for p in states]).T,
        constraint_error=np.array(errors), step=float(step), diverged_at=diverged_at,
    )


def rk4_stability_map(system, s0, sd0, step, alpha_steps, beta_steps, n_steps=100, growth_limit=1.0):
    """The observed stability of RK4 with Baumgarte's (16)-(17) on a grid of ``(alpha dt, beta dt)``.

    For each pair the mechanism is integrated for ``n_steps`` steps of size
    ``step`` from the (inconsistent) state ``(s0, sd0)``, with
    ``Baumgarte(alpha_dt / step, beta_dt / step)``, and the growth of the
    constraint error is returned: a cell is *unstable* when it ends larger than
    ``growth_limit`` times where it began (the caller compares).
    For a system without ``force`` the cells run as one batch (the model's
    generated array functions, one stacked solve of (12) per stage), which
    agrees with :func:`rk4` cell by cell to round-off and costs a few percent
    of it; otherwise each cell is one :func:`rk4` run.

    Parameters
    ----------
    system : System
        Without switched forces.
    s0, sd0 : array_like
        A state slightly off the constraints: ``|f(s0)|`` at least
        :data:`MIN_START_ERROR`, so that the growth measures the error equation (15),
        not round-off.
    step : float
        dt [s]: small against the mechanism's own time scale, so that only the
        error dynamics (15) can make a step too long.
    alpha_steps, beta_steps : 1-d array_like
        The grid of ``alpha dt`` and ``beta dt``.
    n_steps : int, optional
    growth_limit : float, optional
        The growth the caller calls unstable.  It only sets where a cell stops:
        once ``|f|`` exceeds ``1e3 max(growth_limit, 1)`` times where it began, so
        that a diverging cell costs little.

    Returns
    -------
    growth : ndarray, shape (len(beta_steps), len(alpha_steps))
        ``|f|`` at the end over ``|f|`` at the start (a diverged run gives its
        growth when it stopped, above ``1e3 max(growth_limit, 1)``).

    Raises
    ------
    InputError
        For a start whose ``|f(s0)|`` is below :data:`MIN_START_ERROR`, before any step.
    """
    alpha_steps = np.asarray(alpha_steps, dtype=float)
    beta_steps = np.asarray(beta_steps, dtype=float)
    s0, sd0 = np.asarray(s0, dtype=float), np.asarray(sd0, dtype=float)
    start_error = float(np.linalg.norm(system.constraints(s0)))
    if not start_error >= MIN_START_ERROR:
        raise InputError(
            f"s0: must lie off the constraints by |f(s0)| >= {MIN_START_ERROR:g} m, got {start_error:.3g}: the map "
            "is the growth of |f| from there (perturb a dependent coordinate, as chapter 9 does)")
    if system.force is None:               # no force outside the model's own: every cell at once
        positive_number("step", step, unit="s")
        positive_integer("n_steps", n_steps)
        try:
            return _stability_map_at_once(system, s0, sd0, start_error, step, alpha_steps, beta_steps, n_steps,
                                          1e3 * max(growth_limit, 1.0))
        except np.linalg.LinAlgError:
            pass                           # a singular matrix in some cell: the cell's own run names it
    growth = np.empty((beta_steps.size, alpha_steps.size))
    for i, beta_step in enumerate(beta_steps):
        for j, alpha_step in enumerate(alpha_steps):
            formulation = Baumgarte(float(alpha_step / step), float(beta_step / step))
            run = rk4(system, formulation, s0, sd0, step, n_steps, divergence=1e3 * max(growth_limit, 1.0))
            growth[i, j] = np.inf if not np.isfinite(run.constraint_error[-1]) else run.growth
    return growth


def _stability_map_at_once(system, s0, sd0, start_error, step, alpha_steps, beta_steps, n_steps, divergence):
    """:func:`rk4_stability_map` with the cells as the columns of one batch (a system without ``force``).

    The same scheme, gains and stopping rule as :func:`rk4` run cell by cell
    (``Baumgarte(alpha_dt / step, beta_dt / step)``, (16)-(17)); the batch's
    generated functions and solves agree with the one-state ones to round-off.
    A cell stops, as :func:`rk4` does, at the first step whose state is not
    finite (its growth is then the last finite one) or whose ``|f|`` exceeds
    ``divergence`` times where it began (that ``|f|`` is its growth).
    """
    n, r = system.n, system.r
    alpha = np.repeat((alpha_steps / step)[None, :], beta_steps.size, axis=0).ravel()
    beta = np.repeat((beta_steps / step)[:, None], alpha_steps.size, axis=1).ravel()
    size = alpha.size
    limit = divergence * start_error               # |f(s0)| >= MIN_START_ERROR: checked by the caller
    error = np.full(size, start_error)
    active = np.ones(size, dtype=bool)
    y = np.repeat(np.concatenate((s0, sd0))[:, None], size, axis=1)
    matrix = np.zeros((size, n + r, n + r))

    def rhs(t, y, cells):
        s, sd = y[:n], y[n:]
        M, p1, f, Phi, gamma = system.dynamics_many(t, s, sd)
        a, b = alpha[cells], beta[cells]
        p2 = -gamma - 2.0 * a * np.einsum("ijk,jk->ik", Phi, sd) - b * b * f          # (17)
        augmented = matrix[: s.shape[1]]
        augmented[:, :n, :n] = np.moveaxis(M, -1, 0)                                   # (12), (16)
        augmented[:, :n, n:] = np.moveaxis(Phi, -1, 0).transpose(0, 2, 1)
        augmented[:, n:, :n] = np.moveaxis(Phi, -1, 0)
        right = np.concatenate((p1, p2)).T[:, :, None]
        return np.concatenate((sd, np.linalg.solve(augmented, right)[:, :n, 0].T))

    for k in range(n_steps):
        cells = np.flatnonzero(active)
        if cells.size == 0:
            break
        t = k * step
        new = rk4_step(lambda time, state: rhs(time, state, cells), t, y[:, cells], step)
        finite = np.isfinite(new).all(axis=0)
        active[cells[~finite]] = False
        cells, new = cells[finite], new[:, finite]
        y[:, cells] = new
        error[cells] = np.linalg.norm(system.constraints_and_jacobian_many(new[:n])[0], axis=0)
        active[cells[~(error[cells] <= limit)]] = False
    growth = np.where(np.isfinite(error), error / start_error, np.inf)
    return growth.reshape(beta_steps.size, alpha_steps.size)
