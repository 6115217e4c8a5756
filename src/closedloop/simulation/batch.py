"""The batch integrator: many starts of one one-degree-of-freedom system, integrated at once.

Every start ``(q0, q0')`` of the independent coordinate q is a cell; all cells are stepped
together in the minimal-coordinate ODE of :mod:`~closedloop.simulation.batch_model`, by
the classical Runge-Kutta scheme (:func:`closedloop.fixed_step.rk4_step`) with a fixed
step, on one smooth branch of the switched force at a time, as :func:`closedloop.simulate`
runs one branch per segment.  Every switch, stick and release is decided by
:mod:`~closedloop.simulation.switching`, with the same functions as
:class:`~closedloop.simulation.run.Run`:

- a cell whose switching function changes sign in a step is stepped back to the crossing
  (located on the cubic Hermite interpolant of h over the step), and its next branch is
  :func:`~closedloop.simulation.switching.choose_side`'s: the rates on both branches, or,
  where both vanish or the cell stalled there, each branch's probed motion;
- a cell that sticks is held at rest; its release is located between two grid times by
  :func:`~closedloop.simulation.switching.locate_release`;
- the largest excursion ``|q - q0|`` is kept at every step end and switch point; a cell
  that has turned a full revolution (:func:`full_turn`) is finished and, unless asked
  otherwise, leaves the batch.

:mod:`~closedloop.simulation.batch_pool` splits a batch into parts for worker processes
or any :class:`concurrent.futures.Executor`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import hermite
from ..errors import InputError, IntegrationError
from ..fixed_step import rk4_step
from ..validation import finite_array
from . import switching as rule
from .batch_limits import DEFAULT_STEP, check_span, check_step, check_work, step_bound
from .batch_model import BatchModel

__all__ = ["BatchOutcome", "integrate_batch", "full_turn", "FULL_TURN", "DEFAULT_STEP"]

#: The excursion |q - q0| of a full revolution [rad].
FULL_TURN = 2.0 * math.pi


def full_turn(excursion):
    """Where the largest excursion ``max |q(t) - q0|`` [rad] reached :data:`FULL_TURN`: bool (array)."""
    return np.asarray(excursion, dtype=float) >= FULL_TURN


@dataclass
class _Cells:
    """Per-cell state of the batch (arrays of shape (K,) or (k, K))."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    z: np.ndarray
    mode: np.ndarray
    q0: np.ndarray
    excursion: np.ndarray
    stuck: np.ndarray            # index of the switch a cell sticks on, -1 if free
    stuck_since: np.ndarray
    margin: np.ndarray           # the sticking margin at the last check
    done: np.ndarray             # turned a full revolution: finished
    decided_at: np.ndarray       # when a cell turned 2 pi (nan if it did not)
    first_stuck: np.ndarray      # when a cell first stuck (nan if it did not)
    first_release: np.ndarray    # when a stuck cell was first released (nan if it was not)
    events: np.ndarray           # switch events per cell
    stalls: np.ndarray           # consecutive stops at a switch without progress
    cached: np.ndarray           # the stored point of a cell is its current state on its branch
    finish_early: bool = True    # a cell that turned 2 pi leaves the batch
    points: dict = None          # s, sd, sdd, qdd, R, c at each cell's current state


@dataclass(frozen=True)
class BatchOutcome:
    """What :func:`integrate_batch` computed for K cells.

    Attributes
    ----------
    codes : ndarray of int, shape (K,)
        1 where the cell turned a full revolution (:func:`full_turn`), else 0.
    excursion : ndarray, shape (K,)
        Largest ``|q - q0|`` [rad] seen before the cell finished.
    decided_at, stuck_at, released_at : ndarray, shape (K,)
        When a cell turned 2 pi, first stuck, was first released [s]; nan where it did not.
    final_phi, final_dphi : ndarray, shape (K,)
        q and q' at the end.
    switch_events : ndarray of int, shape (K,)
        Located switch crossings, stops and releases per cell.
    evaluations, cell_evaluations : int
        Vectorised evaluations of the accelerations, and the same counted per cell.
    max_constraint_error : float
        Largest |f| (32) at the final states.
    step : float
        The step taken [s] (``t_end`` over a whole number of steps).
    motion : ndarray, shape (K, T), or None
        q at ``sample_times``, if asked for.
    """

    codes: np.ndarray
    excursion: np.ndarray
    decided_at: np.ndarray
    stuck_at: np.ndarray
    released_at: np.ndarray
    final_phi: np.ndarray
    final_dphi: np.ndarray
    switch_events: np.ndarray
    evaluations: int
    cell_evaluations: int
    max_constraint_error: float
    step: float
    motion: np.ndarray = None


def integrate_batch(system, q0, qd0, t_end=20.0, step=DEFAULT_STEP, *, initial_state, progress=None,
                    finish_early=True, sample_times=None):
    """Integrate K starts of a one-degree-of-freedom system at once, and say which turned a full revolution.

    Parameters
    ----------
    system : System
        One degree of freedom; its switched force, if it has one, must provide
        ``switching_functions_many`` and ``many``.
    q0, qd0 : array_like, shape (K,)
        Starts of the independent coordinate q [rad] and of its rate [rad/s].
    t_end : float
        Final time [s], > 0.
    step : float
        Step of the fixed-step Runge-Kutta scheme [s], 0 < step <= t_end, within
        :func:`~closedloop.simulation.batch_limits.check_step`'s bound.
    initial_state : callable, keyword only
        ``initial_state(system, q0, qd0)`` returns the consistent
        :class:`~closedloop.kinematics.InitialState` of one cell: it chooses the assembly
        branch (the dependent coordinates z of f(q, z) = 0 (6)); its q and q' must be
        the cell's own.
    progress : callable, optional
        ``progress(fraction)`` of the time span done, called about a hundred times.
    finish_early : bool, optional
        A cell that has turned a full revolution leaves the batch (its outcome is
        settled); False integrates every cell to ``t_end``.
    sample_times : array_like, optional
        Times [s] in [0, t_end] at which to keep every cell's q (the outcome's
        ``motion``); every cell then runs to ``t_end``.  q is interpolated linearly
        between step ends and switch points.

    Returns
    -------
    BatchOutcome

    Raises
    ------
    InputError
        For starts that are not finite or not paired, a step too coarse for the motion,
        a batch of too many steps, an ``initial_state`` that is not a function or moves a start.
    IntegrationError
        Where a cell's state stops being finite, or a cell chatters on a switch.
    """
    q0 = np.asarray(q0, dtype=float).ravel()
    qd0 = np.asarray(qd0, dtype=float).ravel()
    if q0.shape != qd0.shape:
        raise InputError("phi0, dphi0: need one speed per angle")
    if not (np.all(np.isfinite(q0)) and np.all(np.isfinite(qd0))):
        raise InputError("phi0, dphi0: must be finite numbers")
    if not callable(initial_state):
        raise InputError(f"initial_state: must be a function (system, q0, qd0) -> InitialState, "
                         f"got {initial_state!r}")
    check_span(t_end, step, step_bound(system, qd0)[2])
    check_step(system, step, qd0)
    if sample_times is not None:
        sample_times = finite_array("sample_times", sample_times)
        if np.any(sample_times < 0) or np.any(sample_times > t_end):
            raise InputError(f"sample_times: need a list of times within 0 .. t_end = {t_end:g} s")
        finish_early = False                         # every cell's motion is kept to t_end
    check_work(q0.size, t_end, step)
    model = BatchModel(system)
    cells = _initial_cells(system, model, q0, qd0, initial_state)
    cells.finish_early = finish_early
    count = max(1, int(math.ceil(t_end / step - 1e-9)))
    h = t_end / count
    report = max(1, count // 100)
    track = None if sample_times is None else ([cells.t.copy()], [cells.q.copy()])
    for k in range(1, count + 1):
        T = t_end if k == count else k * h
        _advance(model, cells, T)
        _check_stuck(model, cells, T)
        if k == count:                               # cells stopped at a switch finish the run
            for _ in range(rule.MAX_STALLS * 4):
                if not np.any(~cells.done & (cells.stuck < 0) & (cells.t < T)):
                    break
                _advance(model, cells, T)
        if track is not None:
            track[0].append(cells.t.copy())
            track[1].append(cells.q.copy())
        if progress is not None and (k % report == 0 or k == count):
            progress(k / count)
        if np.all(cells.done):                       # every cell turned 2 pi: nothing left to decide
            if progress is not None and k < count:
                progress(1.0)
            break
    motion = None
    if track is not None:
        times, angles = np.array(track[0]), np.array(track[1])          # (steps + 1, K)
        motion = np.array([np.interp(sample_times, times[:, j], angles[:, j]) for j in range(q0.size)])
        motion = motion.reshape(q0.size, sample_times.size)
    s_final, _ = model.configuration(cells.q, cells.z)
    f_final = system.constraints_and_jacobian_many(s_final)[0]
    return BatchOutcome(
        codes=full_turn(cells.excursion).astype(int), excursion=cells.excursion.copy(),
        decided_at=cells.decided_at, stuck_at=cells.first_stuck, released_at=cells.first_release,
        final_phi=cells.q.copy(), final_dphi=cells.qd.copy(), switch_events=cells.events,
        evaluations=model.evaluations, cell_evaluations=model.cell_evaluations,
        max_constraint_error=float(np.max(np.linalg.norm(f_final, axis=0))), step=h, motion=motion,
    )


def _initial_cells(system, model, q0, qd0, initial_state):
    """Consistent initial states, the initial branch of each switch, and sticking at t = 0.

    ``initial_state(system, q0, qd0)`` chooses each cell's assembly branch (its z); the
    independent coordinate and rate it returns must be the cell's own.
    """
    size = q0.size
    z = np.empty((system.r, size))
    for j in range(size):                      # the caller's branch choice, cell by cell (cheap)
        start = initial_state(system, float(q0[j]), float(qd0[j]))
        q, qd = float(start.s[model.q]), float(start.sd[model.q])
        if abs(q - q0[j]) > 1e-12 * (1.0 + abs(q0[j])) or abs(qd - qd0[j]) > 1e-12 * (1.0 + abs(qd0[j])):
            raise InputError(f"initial_state: returned q = {q!r}, q' = {qd!r} for the cell started at "
                             f"q0 = {float(q0[j])!r}, q0' = {float(qd0[j])!r}; it must keep them")
        z[:, j] = start.s[system.z_index]
    k = model.switches
    cells = _Cells(t=np.zeros(size), q=q0.copy(), qd=qd0.copy(), z=z, mode=np.zeros((k, size), bool),
                   q0=q0.copy(), excursion=np.zeros(size), stuck=np.full(size, -1),
                   stuck_since=np.full(size, np.nan), margin=np.full(size, np.nan),
                   done=np.zeros(size, bool), decided_at=np.full(size, np.nan),
                   first_stuck=np.full(size, np.nan), first_release=np.full(size, np.nan),
                   events=np.zeros(size, int), stalls=np.zeros(size, int), cached=np.zeros(size, bool))
    if k == 0:
        return cells
    point = model.evaluate(0.0, cells.q, cells.qd, cells.z, cells.mode)
    s, sd = point["s"], point["sd"]
    h = model.switching(0.0, s, sd)
    cells.mode = h > 0
    scale = rule.state_scale(s, sd)
    for i in range(k):
        on_surface = np.flatnonzero(rule.on_surface(h[i], scale) & (cells.stuck < 0))
        if on_surface.size:
            _decide(model, cells, on_surface, i, np.zeros(on_surface.size), s[:, on_surface], sd[:, on_surface],
                    np.zeros(on_surface.size, bool))
    return cells


def _decide(model, cells, idx, i, t, s, sd, stalled):
    """The branch of switch i for cells ``idx`` on its surface: :func:`~closedloop.simulation.switching.choose_side`."""
    mode = cells.mode[:, idx]
    off, on = model.side_rates(t, s, sd, cells.q[idx], cells.qd[idx], cells.z[:, idx], mode, i)

    def probed(where):
        return model.probe_rates(t[where], s[:, where], sd[:, where], mode[:, where], i)

    side, sticks = rule.choose_side(off, on, mode[i], rule.state_scale(s, sd), stalled, probed)
    if np.any(sticks) and not model.force.can_stick[i]:
        raise rule.refuse_sliding(t, model.force.switch_names[i])
    cells.mode[i, idx] = side
    cells.cached[idx] = False
    held = idx[sticks]
    cells.stuck[held] = i
    cells.stuck_since[held] = t[sticks]
    cells.qd[held] = 0.0
    cells.margin[held] = rule.release_margin(off, on)[sticks]
    first = held[np.isnan(cells.first_stuck[held])]
    cells.first_stuck[first] = cells.stuck_since[first]
    cells.events[idx] += 1


def _rk4(model, t, dt, q, qd, z, mode, first):
    """One classical Runge-Kutta step of size dt (per cell) on the branch ``mode``, and the point at its end."""
    R0z = first["R"][model.z]

    def slope(time, y):
        return np.stack((y[1], model.evaluate(time, y[0], y[1], z + R0z * (y[0] - q), mode)["qdd"]))

    q_new, qd_new = rk4_step(slope, t, np.stack((q, qd)), dt, k1=np.stack((qd, first["qdd"])))
    end = model.evaluate(t + dt, q_new, qd_new, z + R0z * (q_new - q), mode)
    return q_new, qd_new, end


def _take(point, idx):
    return {key: value[..., idx] for key, value in point.items()}


def _advance(model, cells, T):
    """One step of every free, unfinished cell to time T; a cell that crosses a switch stops there.

    A stopped cell chooses its new branch and waits at the switch: the next
    step takes it from there to the next grid time.
    """
    idx = np.flatnonzero(~cells.done & (cells.stuck < 0) & (cells.t < T))
    if idx.size == 0:
        return
    t0, q0, qd0, z0, mode = cells.t[idx], cells.q[idx], cells.qd[idx], cells.z[:, idx], cells.mode[:, idx]
    first = _first_points(model, cells, idx)
    dt = T - t0
    q1, qd1, end = _rk4(model, t0, dt, q0, qd0, z0, mode, first)
    if model.switches:
        h0 = model.switching(t0, first["s"], first["sd"])
        h1 = model.switching(T, end["s"], end["sd"])
        crossed = (mode & (h1 < 0)) | (~mode & (h1 > 0))
    else:
        crossed = np.zeros((0, idx.size), bool)
    bad = ~(np.isfinite(q1) & np.isfinite(qd1))
    if np.any(bad):
        j = idx[np.argmax(bad)]
        raise IntegrationError(
            f"the state became non-finite in the step ending at t = {T:.6g} s (start phi0 = "
            f"{cells.q0[j]:.6g} rad); use a smaller step"
        )
    hit = np.any(crossed, axis=0)
    calm = ~hit
    # cells that stayed on their branch: accept the step
    keep = idx[calm]
    cells.t[keep] = T
    cells.q[keep], cells.qd[keep], cells.z[:, keep] = q1[calm], qd1[calm], end["s"][model.z][:, calm]
    cells.stalls[keep] = 0
    _record(cells, keep, T)
    _store_points(cells, keep, _take(end, calm))
    if not np.any(hit):
        return
    # cells that crossed a switch: locate the first crossing on the cubic Hermite interpolant
    sub = np.flatnonzero(hit)
    cells_sub = idx[sub]
    cells.cached[cells_sub] = False
    r0 = model.rates(t0[sub], first["s"][:, sub], first["sd"][:, sub], first["sdd"][:, sub])
    r1 = model.rates(T, end["s"][:, sub], end["sd"][:, sub], end["sdd"][:, sub])
    theta = np.full((model.switches, sub.size), np.inf)
    for i in range(model.switches):
        rows = crossed[i, sub]
        start = rule.on_chosen_side(h0[i, sub][rows], mode[i, sub][rows])      # a start on the surface: no root
        theta[i, rows] = hermite.first_root(start, h1[i, sub][rows], dt[sub][rows] * r0[i, rows],
                                            dt[sub][rows] * r1[i, rows])
    which = np.argmin(theta, axis=0)
    fraction = theta[which, np.arange(sub.size)]
    qe, qde, event = _rk4(model, t0[sub], fraction * dt[sub], q0[sub], qd0[sub], z0[:, sub],
                          mode[:, sub], _take(first, sub))
    te = t0[sub] + fraction * dt[sub]
    cells.stalls[cells_sub] = np.where(rule.no_progress(te, t0[sub]), cells.stalls[cells_sub] + 1, 0)
    chattering = cells.stalls[cells_sub] > rule.MAX_STALLS
    if np.any(chattering):
        k = int(np.argmax(chattering))
        raise rule.chattering_error(te[k], model.force.switch_names[which[k]], "use a smaller step")
    cells.t[cells_sub], cells.q[cells_sub], cells.qd[cells_sub] = te, qe, qde
    cells.z[:, cells_sub] = event["s"][model.z]
    _record(cells, cells_sub, te)
    for i in range(model.switches):
        rows = np.flatnonzero((which == i) & ~cells.done[cells_sub])
        if rows.size:
            _decide(model, cells, cells_sub[rows], i, te[rows], event["s"][:, rows], event["sd"][:, rows],
                    cells.stalls[cells_sub[rows]] > 0)


_POINT_KEYS = ("s", "sd", "sdd", "qdd", "R", "c")


def _first_points(model, cells, idx):
    """The state and accelerations at the start of a step: kept from the last step's end where valid."""
    if cells.points is None:
        point = model.evaluate(cells.t[idx], cells.q[idx], cells.qd[idx], cells.z[:, idx], cells.mode[:, idx])
        cells.points = {key: np.empty(value.shape[:-1] + cells.q.shape) for key, value in point.items()}
        _store_points(cells, idx, point)
        return point
    missing = idx[~cells.cached[idx]]
    if missing.size:
        _store_points(cells, missing, model.evaluate(cells.t[missing], cells.q[missing], cells.qd[missing],
                                                     cells.z[:, missing], cells.mode[:, missing]))
    return {key: value[..., idx] for key, value in cells.points.items()}


def _store_points(cells, idx, point):
    if cells.points is None or idx.size == 0:
        return
    for key in _POINT_KEYS:
        cells.points[key][..., idx] = point[key]
    cells.cached[idx] = True


def _record(cells, idx, t):
    """Largest excursion so far; a cell that turned 2 pi is finished."""
    if idx.size == 0:
        return
    cells.excursion[idx] = np.maximum(cells.excursion[idx], np.abs(cells.q[idx] - cells.q0[idx]))
    turned = idx[full_turn(cells.excursion[idx])]
    fresh = turned[np.isnan(cells.decided_at[turned])]
    cells.decided_at[fresh] = np.broadcast_to(t, idx.shape)[np.isin(idx, fresh)]
    if cells.finish_early:
        cells.done[turned] = True


def _rest_margins(model, cells, i, s, rows, t):
    """The release margin of switch i at rest, at times ``t``, for the stuck cells ``rows`` (positions ``s``)."""
    rest = np.zeros_like(s)
    rates = []
    for side in (False, True):
        trial = cells.mode[:, rows].copy()
        trial[i] = side
        sdd = model.rest_accelerations(t, s, trial)
        rates.append(model.rates(t, s, rest, sdd)[i])
    return rates


def _check_stuck(model, cells, T):
    """The sticking rule: a stuck cell is released where the holding force leaves the branches' range.

    The margin is checked at every grid time; where it has become <= 0 the
    release is located between the last check and now by the rule's
    :func:`~closedloop.simulation.switching.locate_release`, as simulate() does.
    """
    idx = np.flatnonzero((cells.stuck >= 0) & ~cells.done)
    if idx.size == 0:
        return
    for i in np.unique(cells.stuck[idx]):
        sub = idx[cells.stuck[idx] == i]
        s, _ = model.configuration(cells.q[sub], cells.z[:, sub])
        off, on = _rest_margins(model, cells, i, s, sub, T)
        margin = rule.release_margin(off, on)
        free = margin <= 0
        if np.any(free):
            cells_free, s_free = sub[free], s[:, free]

            def margins(times, rows):
                return rule.release_margin(*_rest_margins(model, cells, i, s_free[:, rows], cells_free[rows], times))

            cells.t[cells_free] = rule.locate_release(margins, cells.t[cells_free], np.full(cells_free.size, T),
                                                      cells.margin[cells_free], margin[free])
            fresh = cells_free[np.isnan(cells.first_release[cells_free])]
            cells.first_release[fresh] = cells.t[fresh]
            cells.mode[i, cells_free] = rule.side_after_release(off[free])
            cells.stuck[cells_free] = -1
            cells.cached[cells_free] = False
            cells.events[cells_free] += 1
        held = sub[~free]
        cells.margin[held] = margin[~free]
        cells.t[held] = T
