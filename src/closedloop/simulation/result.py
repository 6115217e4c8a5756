"""What simulate() returns, and how the pieces of a run become one result."""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..validation import one_of
from .work import without_work, work_of

__all__ = ["SimulationResult", "SwitchEvent", "Piece", "Outputs", "multipliers", "residual_warnings"]


@dataclass(frozen=True)
class SwitchEvent:
    """One stop at a switching surface: when, which switch, and what happened.

    ``action`` is one of ``"crossed"``, ``"turned back"``, ``"stuck"``, ``"released"``.
    """

    t: float
    switch: str
    action: str


class _Residuals:
    """A residual field of :class:`SimulationResult`: the array given, or, given None, computed from the
    result's ``s`` and ``sd`` when first read (by its ``residuals``, both residuals at once) and kept.

    A descriptor-typed dataclass field: the dataclass's ``__init__`` sets it through ``__set__``,
    and it has no default.
    """

    def __set_name__(self, owner, name):
        self.name, self.slot = name, "_" + name

    def __get__(self, result, owner=None):
        if result is None:
            raise AttributeError(self.name)         # no default: the field is required
        value = result.__dict__[self.slot]
        if value is None and result.residuals is not None:
            result.__dict__["_constraint_error"], result.__dict__["_velocity_constraint_error"] = (
                result.residuals(result.s, result.sd))
            value = result.__dict__[self.slot]
        return value

    def __set__(self, result, value):
        result.__dict__[self.slot] = value


@dataclass
class SimulationResult:
    """What :func:`simulate` computed.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Output times.
    s, sd : ndarray, shape (n, N)
        Coordinates and velocities (rows in the order of the model's coordinates).
    constraint_error : ndarray, shape (N,)
        ``|f| = sqrt(sum f_i^2)`` of (32) at the outputs.
    velocity_constraint_error : ndarray, shape (N,)
        ``|f'| = |Phi_s s'|`` of (9) at the outputs.  :func:`simulate` leaves both
        to be computed from ``s`` and ``sd`` when one of them is first read (by
        ``residuals``, the system's ``constraint_errors``): like lambda, the residuals
        of 10 000 outputs cost only the runs that use them (they cost about a third
        of a one-second run's integration).
    multipliers : ndarray, shape (r, N), or None
        lambda of (5), only when asked for.
    nfev : int
        Right-hand-side evaluations, summed over all segments.
    cpu_time : float
        Process time of the run in seconds (integration, switching, outputs; not the
        residuals at the outputs, computed when first read, nor the multipliers of (5),
        nor the loading of modules that the process imports on first use:
        :mod:`closedloop.loading`).
    switch_events : list of SwitchEvent
    sticking_intervals : list of (float, float)
        Time intervals spent stuck (see :mod:`closedloop.simulation.switching`).
    stopped_at : float or None
        Where ``stop_when`` ended the run early, else None.
    partition_singularities : list of float
        Times where det Phi_z of the model's partition changed sign (dead
        positions passed by a redundant-coordinate formulation).
    switching : str
        "events" or "naive" (see :func:`simulate`).
    formulation, method : str
        ``formulation`` is the formulation's registry name, so
        ``formulation_from_name(result.formulation)`` gives it back.
    rtol, atol : float
    coordinate_names : tuple of str
    step_sizes : ndarray, shape (n_steps,)
        Every accepted step of the integrator [s], in order, over all segments.
        A step that crossed a switch counts whole: it ends beyond the switch,
        where the next segment begins.
    step_starts : ndarray, shape (n_steps,)
        The time [s] at which each of those steps began: with ``step_sizes``,
        what to plot a step size against (their running sum is not the time:
        it runs past every switch, and it skips the intervals at rest).
    work : ndarray, shape (N,), or None
        Only with ``work=True``: the work W(t) [J] done since ``t_start`` by the
        non-conservative generalised forces tau of (5) (the model's smooth
        forces and the switched force), integrated with the state.
    step_constraint_error, step_velocity_constraint_error : float
        The largest |f| and |f'| at the integrator's step ends, over the whole
        run (0 when the change-point watch is off, ``branch_limit=math.inf``).
    residuals : callable or None
        ``residuals(s, sd) -> (|f|, |f'|)`` at every column, for the residual
        fields given as None.
    warnings : list of str
        Why this result should not be trusted (see :func:`residual_warnings`, applied
        to the largest residuals, at the outputs and the step ends);
        empty for a result whose own residuals are within the run's bound.
        The command line prints them, and :func:`closedloop.slider_crank.classify_motion`
        refuses a result that has any.
    """

    t: np.ndarray
    s: np.ndarray
    sd: np.ndarray
    constraint_error: np.ndarray = _Residuals()
    velocity_constraint_error: np.ndarray = _Residuals()
    multipliers: np.ndarray | None
    nfev: int
    cpu_time: float
    switch_events: list = field(default_factory=list)
    sticking_intervals: list = field(default_factory=list)
    stopped_at: float | None = None
    partition_singularities: list = field(default_factory=list)
    switching: str = "events"
    formulation: str = ""
    method: str = ""
    rtol: float = math.nan
    atol: float = math.nan
    coordinate_names: tuple = ()
    step_sizes: np.ndarray = field(default_factory=lambda: np.empty(0))
    step_starts: np.ndarray = field(default_factory=lambda: np.empty(0))
    work: np.ndarray | None = None
    step_constraint_error: float = 0.0
    step_velocity_constraint_error: float = 0.0
    residuals: object = field(default=None, repr=False, compare=False)

    @property
    def warnings(self) -> list:
        """Why this result should not be trusted: :func:`residual_warnings` of its largest residuals."""
        speed = float(np.max(np.abs(self.sd), initial=0.0))
        return residual_warnings(self.max_constraint_error, self.max_velocity_constraint_error, speed, self.rtol,
                                 self.atol)

    @property
    def n_steps(self) -> int:
        """Accepted integration steps, summed over all segments."""
        return int(self.step_sizes.size)

    @property
    def max_constraint_error(self) -> float:
        """The maximum of |f| of (32) over the run: output points and step ends."""
        return float(max(np.max(self.constraint_error, initial=0.0), self.step_constraint_error))

    @property
    def max_velocity_constraint_error(self) -> float:
        """The maximum of |f'| of (9) over the run: output points and step ends."""
        return float(max(np.max(self.velocity_constraint_error, initial=0.0), self.step_velocity_constraint_error))

    def coordinate(self, name):
        """The row of ``s`` for the coordinate called ``name``."""
        return self.s[self.coordinate_names.index(one_of("name", name, self.coordinate_names))]

    def velocity(self, name):
        """The row of ``sd`` for the coordinate called ``name``."""
        return self.sd[self.coordinate_names.index(one_of("name", name, self.coordinate_names))]


class Piece(NamedTuple):
    """Output of one segment of a run, or of one stuck interval."""

    t: np.ndarray            # shape (N,)
    s: np.ndarray            # shape (n, N)
    sd: np.ndarray           # shape (n, N)
    mode: tuple | None       # the force's branch (None for a naive run)
    stuck: int | None        # the switch a stuck piece is held on, else None
    work: np.ndarray | None  # W(t), only when the run tracks work


class Outputs:
    """The output points of a run: which requested times are still due, and the pieces so far."""

    def __init__(self, t_eval):
        self.t_eval = t_eval
        self.pieces = []
        self.next = 0                  # index into t_eval of the next time due

    def due(self, t0, until=None):
        """The requested times from ``t0`` on (up to ``until``), or None for "every step"."""
        if self.t_eval is None:
            return None
        rest = self.t_eval[self.next:]                # increasing (simulate checked t_eval): cut by bisection
        if t0 is not None:
            rest = rest[rest.searchsorted(t0, "left"):]
        return rest if until is None else rest[:rest.searchsorted(until, "right")]

    def add_segment(self, t, y, unpack, mode, t0, work_row):
        """Store a segment's output (states ``y`` unpacked to s, s'); ``work_row``: y carries W last."""
        if self.t_eval is not None:
            self.next += t.size
        elif self.pieces and t.size and t[0] == t0:
            t, y = t[1:], y[:, 1:]           # the first point repeats the last segment's end
        if t.size == 0:
            return
        work = work_of(y) if work_row else None
        y = without_work(y, work_row)
        s, sd = unpack.many(y, t)           # rule 3 of the formulation contract: in order along the path
        self.pieces.append(Piece(t, s, sd, mode, None, work))

    def add_rest(self, times, s, mode, stuck, work):
        """Store the output of an interval at rest at ``s``."""
        if self.t_eval is not None:
            self.next += times.size
        if times.size:
            self.pieces.append(Piece(times, np.repeat(s[:, None], times.size, 1),
                                     np.zeros((s.size, times.size)), mode, stuck, work))

    def assemble(self, track_work):
        """``(t, s, sd, modes, work)`` of the whole run, with repeated times at joins dropped.

        ``modes`` is a function that returns the list of ``(mode, stuck)`` of every output point
        (a Python object per point: built only when asked for, by the multipliers).
        """
        pieces = self.pieces
        if len(pieces) == 1:                 # one piece: its arrays, not a copy, and its times increase
            piece = pieces[0]
            return piece.t, piece.s, piece.sd, lambda: [(piece.mode, piece.stuck)] * piece.t.size, piece.work
        t = np.concatenate([p.t for p in pieces])
        s = np.concatenate([p.s for p in pieces], axis=1)
        sd = np.concatenate([p.sd for p in pieces], axis=1)
        keep = np.concatenate(([True], np.diff(t) > 0))

        def modes():
            return list(itertools.compress(itertools.chain.from_iterable(
                itertools.repeat((p.mode, p.stuck), p.t.size) for p in pieces), keep.tolist()))

        if keep.all():                       # no repeated time: nothing to drop
            work = np.concatenate([p.work for p in pieces]) if track_work else None
            return t, s, sd, modes, work
        work = np.concatenate([p.work for p in pieces])[keep] if track_work else None
        return t[keep], s[:, keep], sd[:, keep], modes, work


def multipliers(system, formulation, t, s, sd, modes):
    """lambda of (5) at each output point, from (8): Phi_s^T lambda = p1 - M s''.

    While stuck (s'' = 0), the holding force of the stuck switch is a further
    unknown acting along dh/ds', solved together with lambda.
    """
    lam = np.empty((system.r, t.size))
    h = system.force.switching_functions if system.force is not None else None
    for k in range(t.size):
        mode, stuck = modes[k]
        M, p1, f, Phi, gamma = system.dynamics(t[k], s[:, k], sd[:, k], mode)
        if stuck is None:
            sdd = formulation.accelerations(system, t[k], s[:, k], sd[:, k], mode)
            lam[:, k] = np.linalg.lstsq(Phi.T, p1 - M @ sdd, rcond=None)[0]
        else:
            eps = 1e-7
            direction = np.array([(h(t[k], s[:, k], sd[:, k] + eps * e)[stuck] - h(t[k], s[:, k], sd[:, k])[stuck]) / eps
                                  for e in np.eye(system.n)])
            A = np.column_stack((Phi.T, direction))
            lam[:, k] = np.linalg.lstsq(A, p1, rcond=None)[0][:system.r]
    return lam


def _largest(tolerance):
    """The largest entry of a tolerance: a float as it is (no numpy call), else of its array."""
    return tolerance if isinstance(tolerance, float) else np.max(tolerance)


def residual_warnings(constraint_error, velocity_constraint_error, max_speed, rtol, atol):
    """Why a run's own residuals say that it is meaningless: a list of sentences, empty if none.

    A run integrated with tolerance ``tol = max(rtol, atol)`` keeps |f| of (32)
    and |f'| of (9) far below ``sqrt(tol)`` when it means anything: the
    stabilised formulations hold them near ``10 tol``, and the uncorrected
    drift (13) of Augmented stays under ``sqrt(tol)`` over 40 s for
    tol <= 1e-6 in the paper's four cases.  Above

        |f| > sqrt(tol)    or    |f'| > sqrt(tol) (1 + max |s'|)

    the mechanism has come apart by more than the accuracy asked for allows
    (Augmented at rtol 1e-3 reaches |f| = 4 m), and its motion is not an answer.
    """
    tol = float(max(_largest(rtol), _largest(atol)))
    bound = math.sqrt(tol)
    warnings = []
    if not math.isfinite(constraint_error) or constraint_error > bound:
        warnings.append(f"the constraint error max |f| = {constraint_error:.3g} exceeds sqrt(tolerance) = "
                        f"{bound:.3g}: the mechanism came apart, so this motion is not an answer; tighten rtol "
                        "and atol or use a stabilised formulation")
    velocity_bound = bound * (1.0 + max_speed)
    if not math.isfinite(velocity_constraint_error) or velocity_constraint_error > velocity_bound:
        warnings.append(f"the velocity constraint error max |f'| = {velocity_constraint_error:.3g} exceeds "
                        f"sqrt(tolerance) (1 + max |s'|) = {velocity_bound:.3g}: this motion is not an answer; "
                        "tighten rtol and atol or use a stabilised formulation")
    return warnings
