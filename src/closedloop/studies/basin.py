"""The basin map: which initial conditions (phi0, phi0') end in full rotation, which in a swing.

The paper's conclusion (section 5) says that the motion of the slider-crank
depends on its initial conditions and shows four of them.  This module
classifies a whole grid of them, fast enough to recompute on a laptop.

The batch integrator
--------------------
The mechanism has one degree of freedom, so every cell of the grid is a
state ``(phi, phi')`` of the minimal-coordinate ODE of :class:`~closedloop.Minimal`
(coordinate partitioning with R of (20))::

    (R^T M R) phi'' = R^T (p1 - M c),   c = [0; -Phi_z^{-1} Phi_s' s']

All cells are integrated at once, with arrays of shape (K,) in place of each
number: the dependent coordinates psi, x_C by a vectorised Newton on (27)-(28),
M, p1, Phi_s and Phi_s' s' from the library's derived model lambdified for numpy
(:func:`closedloop.model.array_functions`), the gas force from
:meth:`~closedloop.slider_crank.GasForce.many`.

The method is the classical Runge-Kutta scheme of order 4 with a fixed step,
on one smooth branch of the switched force at a time, as :func:`closedloop.simulate`
does with solve_ivp:

- after each step, a cell whose switching function changed sign (x_C' = 0 or
  x_C = 5) is sent back: the crossing is located on the cubic Hermite
  interpolant of the switching function over the step, the cell is stepped to
  the crossing on its old branch, the new branch is chosen by the same rule as
  simulate() (the rates of the switching function on both sides), and the cell
  finishes the step on the new branch;
- a cell whose slider stops with both branches pushing onto x_C' = 0 is held at
  rest (the sticking rule of :mod:`closedloop.simulation`) until the holding
  force leaves the range between the branches;
- a cell is classified by :func:`closedloop.slider_crank.motion_codes`, the rule
  of :func:`~closedloop.slider_crank.classify_motion`, applied to the largest
  excursion ``|q - q0|`` of the independent coordinate (phi for the slider-crank)
  seen at the step ends and switch points; a cell that has turned 2 pi is
  finished and leaves the batch.

:func:`integrate_outcomes` works for any one-degree-of-freedom
:class:`~closedloop.model.System` (the four-bar of :mod:`closedloop.four_bar` too):
the caller says how a start ``(q0, q0')`` is assembled, through ``initial_state``.
:func:`basin_map` is its slider-crank wrapper, with the slider-crank's
:func:`~closedloop.slider_crank.initial_state`.

:func:`reference_outcomes` classifies cells one by one with :func:`closedloop.simulate`
(ClosedForm, ode.dop853, rtol = 1e-10: :data:`REFERENCE`) for the agreement check.
"""

from __future__ import annotations

import math
import multiprocessing
import os
import time
from dataclasses import dataclass, field

import numpy as np

from .. import __version__, hermite
from ..errors import InputError, IntegrationError
from ..formulations import ClosedForm
from ..formulations.minimal import minimal_accelerations
from ..kinematics import solve_dependent_many
from ..linalg import orthogonal_complement_many
from ..simulation import simulate
from ..simulation import switching as rule
from ..slider_crank import (ANGLE_LIMIT, DEFAULT_READING, MOTIONS, SPEED_LIMIT, SliderCrankSystem, get_reading,
                            motion_codes, slider_crank_system)
from ..slider_crank import initial_state as slider_crank_initial_state
from ..validation import finite_array, finite_number, positive_integer, positive_number

__all__ = ["BasinMap", "BasinMotions", "basin_map", "integrate_outcomes", "reference_outcomes", "boundary_cells",
           "compare_outcomes", "Agreement", "DEFAULT_STEP", "MAX_STEPS", "grid_values"]

#: Step of the fixed-step scheme [s]; its choice is measured in the book's basin chapter.
DEFAULT_STEP = 0.02
#: The largest angle the fastest rate of a map may turn in one step [rad] (see _check_step).
#: Measured on an 8 x 8 map of the slider-crank (dphi0 < 6 rad/s, forcing period 1 s) against
#: simulate: steps 0.02, 0.05 and 0.1 s give it cell for cell, 0.2 s gets 1 cell wrong, 1 s 4 (measured
#: before this bound; it now refuses 0.1 s there, since the forcing turns 2 pi x 0.1 = 0.63 rad in it);
#: the book's convergence study (chapter 12) starts at 0.08 s, 0.5 rad of the forcing.
MAX_ANGLE_PER_STEP = 0.6
#: The most cell-steps (cells x t_end / step) a map may ask for, over all its workers: a 60 x 60 map
#: over 20 s is 3.6e6 and takes about half a minute on one core, so 1e9 would take hours.
MAX_CELL_STEPS = 1e9
#: Most steps of one map (t_end / step): a step of the batch costs about 1 ms, so 1e5 steps take some
#: 100 s (a 20 s map down to a step of 2e-4 s); the book's maps take 1000.
MAX_STEPS = 100_000


def grid_values(start, stop, count, name="grid"):
    """``count`` evenly spaced values from ``start`` to ``stop``, ``stop`` left out.

    ``start + k (stop - start) / count`` for k = 0 .. count - 1, so that phi0
    in [0, 2 pi) does not count the same angle twice, and a grid of 4m cells
    on [0, 2 pi) holds pi/2 and pi exactly.  A map draws each sample as the
    cell centred on it.  ``name`` is the grid's name in an error message.
    """
    start, stop = finite_number(f"{name} start", start), finite_number(f"{name} stop", stop)
    count = positive_integer(f"{name} count", count)
    if not math.isfinite(stop - start):                 # 1e308 - (-1e308): no spacing to take
        raise InputError(f"{name}: stop - start must be a finite number, got {stop:g} - {start:g}")
    return start + (stop - start) * (np.arange(count) / count)     # k / count: exactly 1/4, 1/2 at k = m, 2m


class _Model:
    """The minimal-coordinate ODE of a one-degree-of-freedom System, on arrays of states."""

    def __init__(self, system):
        if system.f != 1:
            raise InputError(f"system: the batch integrator needs one degree of freedom, got f = {system.f}")
        self.system = system
        self.q = int(system.q_index[0])
        self.z = system.z_index
        self.force = system.force
        self.switches = len(self.force.switch_names) if self.force is not None else 0
        self.evaluations = 0           # vectorised acceleration evaluations
        self.cell_evaluations = 0      # the same, counted per cell

    def configuration(self, q, z_guess):
        """s and Phi_s with s[q] = q and z from Newton on f(q, z) = 0 (6), started at z_guess."""
        return solve_dependent_many(self.system, q, z_guess)

    def evaluate(self, t, q, qd, z_guess, mode):
        """The state and its accelerations at K cells, each on its branch ``mode[:, j]``.

        Returns a dict with s, sd, sdd (n, K), qdd (K,), R (n, K) and c (n, K).
        """
        s, Phi = self.configuration(q, z_guess)
        point = self._accelerations(t, s, Phi, qd, mode)
        point["s"] = s
        return point

    def _accelerations(self, t, s, Phi, qd, mode):
        system = self.system
        size = s.shape[1]
        R = orthogonal_complement_many(Phi, system.q_index, self.z)      # (20), shape (n, 1, K)
        sd = R[:, 0] * qd
        M, p1, _, _, gamma = system.dynamics_many(t, s, sd)
        if self.force is not None:
            p1 = p1 + self.force.many(t, s, sd, mode)
        qdd, c = minimal_accelerations(M, p1, Phi, gamma, R, self.z)
        qdd, R = qdd[0], R[:, 0]
        self.evaluations += 1
        self.cell_evaluations += size
        return {"sd": sd, "sdd": R * qdd + c, "qdd": qdd, "R": R, "c": c}

    def rest_accelerations(self, t, s, mode):
        """s'' at rest (s' = 0) on branch ``mode``."""
        Phi = self.system.constraints_and_jacobian_many(s)[1]
        return self._accelerations(t, s, Phi, np.zeros(s.shape[1]), mode)["sdd"]

    def switching(self, t, s, sd):
        return self.force.switching_functions_many(t, s, sd)

    def rates(self, t, s, sd, sdd):
        """dh/dt of every switching function along the motion (the rule's :func:`switching_rate`)."""
        return rule.switching_rate(self.switching, t, s, sd, sdd)

    def side_rates(self, t, s, sd, q, qd, z, mode, i):
        """Rates of switch i on its "off" and "on" branches at the given states (one switch for all)."""
        size = q.size
        trial = np.concatenate((mode, mode), axis=1)          # both branches in one evaluation
        trial[i, :size], trial[i, size:] = False, True
        t2 = np.concatenate((np.broadcast_to(t, (size,)),) * 2)
        point = self.evaluate(t2, np.tile(q, 2), np.tile(qd, 2), np.tile(z, 2), trial)
        rates = self.rates(t2, np.tile(s, 2), point["sd"], point["sdd"])[i]
        return rates[:size], rates[size:]


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
    stalls: np.ndarray = None    # consecutive stops at a switch without progress
    finish_early: bool = True    # a cell that turned 2 pi leaves the batch
    cached: np.ndarray = None    # the stored point of a cell is its current state on its branch
    points: dict = None          # s, sd, sdd, qdd, R, c at each cell's current state


@dataclass(frozen=True)
class BatchOutcome:
    """What :func:`integrate_outcomes` computed for K cells."""

    codes: np.ndarray            # 0 oscillation, 1 full rotation (MOTIONS)
    excursion: np.ndarray        # largest |phi - phi0| seen before the cell finished [rad]
    decided_at: np.ndarray       # time a cell turned 2 pi [s], nan for a swing
    stuck_at: np.ndarray         # first time a cell's slider stuck [s], nan if never
    released_at: np.ndarray      # first time a stuck cell was released [s], nan if never
    final_phi: np.ndarray
    final_dphi: np.ndarray
    switch_events: np.ndarray    # located switch crossings and stops per cell
    evaluations: int             # vectorised evaluations of the accelerations
    cell_evaluations: int        # the same, summed over the cells evaluated
    max_constraint_error: float  # largest |f| (32) at the final states
    step: float
    motion: np.ndarray = None    # q at the sample times, shape (K, T), if asked for (``sample_times``)


@dataclass(frozen=True)
class BasinMotions:
    """phi(t) of every cell of a basin map, from the map's own integrator (``basin_map(..., motions=...)``).

    Attributes
    ----------
    times : ndarray, shape (T,)
        Sample times [s], 0 to the map's ``t_end``.
    phi : ndarray, shape (M, N, T)
        Crank angle phi [rad] of cell (row, column) at each sample time (not wrapped).
    excursion : ndarray, shape (M, N)
        Largest |phi - phi0| [rad] over the whole run, at every step end and switch point
        (not only the samples).
    step : float
        Step of the batch integrator [s], the map's.
    """

    times: np.ndarray
    phi: np.ndarray
    excursion: np.ndarray
    step: float


def _motion_times(t_end, sample):
    """Times from 0 to t_end [s], at the spacing nearest ``sample`` (> 0 s) that divides t_end evenly
    (``t_end / round(t_end / sample)``), at which a map's motions are kept."""
    t_end = positive_number("t_end", t_end, unit="s")
    sample = positive_number("motions", sample, unit="s")
    if sample > t_end:
        raise InputError(f"motions: the sample spacing must be <= t_end = {t_end:g} s, got {sample:g} s")
    return np.linspace(0.0, t_end, int(round(t_end / sample)) + 1)


def integrate_outcomes(system, phi0, dphi0, t_end=20.0, step=DEFAULT_STEP, progress=None, finish_early=True, *,
                       initial_state=None, sample_times=None):
    """Integrate K initial conditions at once and classify each (the batch integrator).

    Parameters
    ----------
    system : System
        A one-degree-of-freedom system, e.g. :func:`~closedloop.slider_crank.slider_crank_system`
        or a :class:`~closedloop.model.System` of :func:`closedloop.four_bar.four_bar_model`;
        its switched force, if it has one, must provide ``switching_functions_many`` and ``many``.
    phi0, dphi0 : ndarray, shape (K,)
        Initial values of the independent coordinate q [rad] and of its rate [rad/s]
        (for the slider-crank, the crank angle phi and speed phi').
    t_end : float
        Final time [s], > 0.
    step : float
        Step of the fixed-step Runge-Kutta scheme [s], 0 < step <= t_end.
    progress : callable, optional
        ``progress(fraction)`` with a fraction of the time span done, called
        about a hundred times.
    finish_early : bool, optional
        Stop integrating a cell once it has turned 2 pi (its outcome is then
        settled); False integrates every cell to ``t_end``.
    initial_state : callable, optional, keyword only
        ``initial_state(system, q0, qd0)`` returns the consistent
        :class:`~closedloop.kinematics.InitialState` of one cell (it chooses the
        assembly branch, the dependent coordinates z of f(q, z) = 0 (6)); its
        independent coordinate and rate must be q0 and qd0.  Default: for a
        :class:`~closedloop.slider_crank.SliderCrankSystem`,
        :func:`closedloop.slider_crank.initial_state`; any other system must pass one.
    sample_times : array_like, optional, keyword only
        Times [s] in [0, t_end] at which to keep every cell's q (its motion): the
        result's ``motion``, shape (K, T).  Every cell is then integrated to
        ``t_end`` (as with ``finish_early=False``, so ``excursion`` is that of the
        whole run); q is interpolated linearly between the step ends, and a cell
        that stopped at a switch, less than a step behind, between its own times.

    Returns
    -------
    BatchOutcome
        Each cell classified by the largest excursion ``|q - q0|`` of its
        independent coordinate (``codes``, ``excursion``).
    """
    phi0 = np.asarray(phi0, dtype=float).ravel()
    dphi0 = np.asarray(dphi0, dtype=float).ravel()
    if phi0.shape != dphi0.shape:
        raise InputError("phi0, dphi0: need one speed per angle")
    if not (np.all(np.isfinite(phi0)) and np.all(np.isfinite(dphi0))):
        raise InputError("phi0, dphi0: must be finite numbers")
    _check_time(t_end, step, _step_bound(system, dphi0)[2])
    _check_step(system, step, dphi0)
    if sample_times is not None:
        sample_times = finite_array("sample_times", sample_times)
        if np.any(sample_times < 0) or np.any(sample_times > t_end):
            raise InputError(f"sample_times: need a list of times within 0 .. t_end = {t_end:g} s")
        finish_early = False                         # every cell's motion is kept to t_end
    _check_work(phi0.size, t_end, step)
    model = _Model(system)
    initial_state = _start_rule(system, initial_state)
    cells = _initial_cells(system, model, phi0, dphi0, initial_state)
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
        motion = np.array([np.interp(sample_times, times[:, j], angles[:, j]) for j in range(phi0.size)])
        motion = motion.reshape(phi0.size, sample_times.size)
    s_final, _ = model.configuration(cells.q, cells.z)
    f_final = system.constraints_and_jacobian_many(s_final)[0]
    return BatchOutcome(
        codes=motion_codes(cells.excursion), excursion=cells.excursion.copy(), decided_at=cells.decided_at,
        stuck_at=cells.first_stuck, released_at=cells.first_release, final_phi=cells.q.copy(), final_dphi=cells.qd.copy(),
        switch_events=cells.events, evaluations=model.evaluations, cell_evaluations=model.cell_evaluations,
        max_constraint_error=float(np.max(np.linalg.norm(f_final, axis=0))), step=h, motion=motion,
    )


def _shown(value, up):
    """``value`` in 3 significant digits, rounded up (a lower bound) or down (an upper bound), so that the number
    a message advises passes the check that it advises for."""
    text = float(f"{value:.3g}")
    if (text < value) if up else (text > value):
        unit = 10.0 ** (math.floor(math.log10(abs(value))) - 2)
        text = float(f"{text + unit if up else text - unit:.3g}")
    return f"{text:g}"


def _check_time(t_end, step, longest=math.inf):
    """Refuse a t_end and step whose run needs more than MAX_STEPS steps, or a step beyond t_end.

    ``longest`` is the longest step that resolves the map (:func:`_step_bound`): where even it
    needs more than MAX_STEPS steps, only a shorter t_end helps, and the message says so.
    """
    t_end = positive_number("t_end", t_end, unit="s")
    step = positive_number("step", step, unit="s")
    if step > t_end:
        raise InputError(f"step: must be <= t_end = {t_end:g} s, got {step:g} s")
    if t_end / step > MAX_STEPS:
        if t_end / MAX_STEPS > longest:
            raise InputError(f"t_end: {t_end:g} s would take more than {MAX_STEPS:g} steps (about 1 ms each), even of "
                             f"the longest step that resolves this map, {_shown(longest, up=False)} s; give a t_end "
                             f"<= {_shown(MAX_STEPS * step * (1 - 1e-9), up=False)} s (with this step of {step:g} s), "
                             f"or <= {_shown(MAX_STEPS * float(_shown(longest, up=False)) * (1 - 1e-9), up=False)} s "
                             f"with a step of {_shown(longest, up=False)} s")
        raise InputError(f"step: t_end/step would be {t_end / step:.3g} steps, more than {MAX_STEPS:g} (about 1 ms "
                         f"each); give a step >= {_shown(t_end / MAX_STEPS, up=True)} s or a shorter t_end, got "
                         f"{step:g} s")


def _check_work(cells, t_end, step):
    """Refuse a map of more than :data:`MAX_CELL_STEPS` cell-steps (all its cells, whatever the workers)."""
    work = cells * t_end / step
    if work > MAX_CELL_STEPS:
        raise InputError(f"t_end: {cells} cells x t_end / step = {work:.3g} cell-steps, more than the "
                         f"{MAX_CELL_STEPS:.0e} a map may take (hours of CPU); use fewer cells, a shorter "
                         "t_end or a larger step")


def _check_step(system, step, rates):
    """Refuse a step too coarse for the motion: the fastest rate of the map times the step.

    The rates are the cells' starting speeds |q0'| and the forcing's 2 pi / P (P its period,
    read off the model by :func:`~closedloop.simulation.switching.forcing_period`; none for an
    autonomous system, and 2 pi rad/s when the period is unknown).  Their largest, times the
    step, must stay below :data:`MAX_ANGLE_PER_STEP`.
    """
    fastest, source, _ = _step_bound(system, rates)
    if fastest * step > MAX_ANGLE_PER_STEP:
        raise InputError(
            f"step: {step:g} s can not resolve this map: its fastest rate is {fastest:.3g} rad/s ({source}), "
            f"so the step must be <= {MAX_ANGLE_PER_STEP / fastest:.3g} s (at most {MAX_ANGLE_PER_STEP:g} rad "
            "per step)")


def _step_bound(system, rates):
    """``(fastest rate, which one it is, the longest step that resolves it)`` of a map (see :func:`_check_step`)."""
    period = rule.forcing_period(system)
    forcing = 0.0 if period == 0.0 else 2.0 * math.pi / (period if period else 1.0)
    fastest = max(float(np.max(np.abs(rates), initial=0.0)), forcing)
    source = "the forcing's 2 pi / period" if forcing >= fastest else "the largest starting speed |dphi0|"
    return fastest, source, (MAX_ANGLE_PER_STEP / fastest if fastest > 0 else math.inf)


def _start_rule(system, initial_state):
    """The function that assembles a cell's start: the caller's, or the slider-crank's by default."""
    if initial_state is None:
        if not isinstance(system, SliderCrankSystem):
            raise InputError("initial_state: needed for a system other than the slider-crank: a function "
                             "initial_state(system, q0, qd0) that returns a consistent InitialState")
        return slider_crank_initial_state
    if not callable(initial_state):
        raise InputError(f"initial_state: must be a function (system, q0, qd0) -> InitialState, "
                         f"got {initial_state!r}")
    return initial_state


def _initial_cells(system, model, phi0, dphi0, initial_state):
    """Consistent initial states, the initial branch of each switch, and sticking at t = 0.

    ``initial_state(system, q0, qd0)`` chooses each cell's assembly branch (its z); the
    independent coordinate and rate it returns must be the cell's own.
    """
    size = phi0.size
    z = np.empty((system.r, size))
    for j in range(size):                      # the caller's branch choice, cell by cell (cheap)
        start = initial_state(system, float(phi0[j]), float(dphi0[j]))
        q, qd = float(start.s[model.q]), float(start.sd[model.q])
        if abs(q - phi0[j]) > 1e-12 * (1.0 + abs(phi0[j])) or abs(qd - dphi0[j]) > 1e-12 * (1.0 + abs(dphi0[j])):
            raise InputError(f"initial_state: returned q = {q!r}, q' = {qd!r} for the cell started at "
                             f"q0 = {float(phi0[j])!r}, q0' = {float(dphi0[j])!r}; it must keep them")
        z[:, j] = start.s[system.z_index]
    k = model.switches
    cells = _Cells(t=np.zeros(size), q=phi0.copy(), qd=dphi0.copy(), z=z, mode=np.zeros((k, size), bool),
                   q0=phi0.copy(), excursion=np.zeros(size), stuck=np.full(size, -1),
                   stuck_since=np.full(size, np.nan), margin=np.full(size, np.nan),
                   done=np.zeros(size, bool), decided_at=np.full(size, np.nan),
                   first_stuck=np.full(size, np.nan), first_release=np.full(size, np.nan), events=np.zeros(size, int), cached=np.zeros(size, bool),
                   stalls=np.zeros(size, int))
    if k == 0:
        return cells
    point = model.evaluate(0.0, cells.q, cells.qd, cells.z, cells.mode)
    s, sd = point["s"], point["sd"]
    h = model.switching(0.0, s, sd)
    cells.mode = h > 0
    scale = 1.0 + np.abs(np.concatenate((s, sd))).max(axis=0)
    for i in range(k):
        on_surface = np.flatnonzero(rule.on_surface(h[i], scale) & (cells.stuck < 0))
        if on_surface.size:
            _decide(model, cells, on_surface, i, 0.0, s[:, on_surface], sd[:, on_surface])
    return cells


def _decide(model, cells, idx, i, t, s, sd):
    """The branch of switch i for cells ``idx`` on its surface: the rule of :mod:`closedloop.simulation.switching`."""
    off, on = model.side_rates(t, s, sd, cells.q[idx], cells.qd[idx], cells.z[:, idx], cells.mode[:, idx], i)
    mode, sticks = rule.decide(off, on, cells.mode[i, idx])
    if np.any(sticks) and not model.force.can_stick[i]:
        raise rule.refuse_sliding(t, model.force.switch_names[i])
    cells.mode[i, idx] = mode
    cells.cached[idx] = False
    held = idx[sticks]
    cells.stuck[held] = i
    cells.stuck_since[held] = np.broadcast_to(t, idx.shape)[sticks]
    cells.qd[held] = 0.0
    cells.margin[held] = rule.release_margin(off, on)[sticks]
    first = held[np.isnan(cells.first_stuck[held])]
    cells.first_stuck[first] = cells.stuck_since[first]
    cells.events[idx] += 1


def _rk4(model, t, dt, q, qd, z, mode, first):
    """One classical Runge-Kutta step of size dt (per cell) on the branch ``mode``."""
    R0z = first["R"][model.z]

    def stage(tt, qq, vv):
        return model.evaluate(tt, qq, vv, z + R0z * (qq - q), mode)["qdd"]

    a1, v1 = first["qdd"], qd
    v2 = qd + 0.5 * dt * a1
    a2 = stage(t + 0.5 * dt, q + 0.5 * dt * v1, v2)
    v3 = qd + 0.5 * dt * a2
    a3 = stage(t + 0.5 * dt, q + 0.5 * dt * v2, v3)
    v4 = qd + dt * a3
    a4 = stage(t + dt, q + dt * v3, v4)
    q_new = q + dt / 6.0 * (v1 + 2.0 * v2 + 2.0 * v3 + v4)
    qd_new = qd + dt / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
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
        theta[i, rows] = hermite.first_root(h0[i, sub][rows], h1[i, sub][rows], dt[sub][rows] * r0[i, rows],
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
        if rows.size == 0:
            continue
        before = cells.mode[i, cells_sub[rows]].copy()
        _decide(model, cells, cells_sub[rows], i, te[rows], event["s"][:, rows], event["sd"][:, rows])
        # Grazing at the start of the step (both rates zero, e.g. at rest at a dead centre): the rule
        # keeps the branch, so the cell would come straight back; it leaves to the side it went.
        graze = (fraction[rows] == 0) & (cells.mode[i, cells_sub[rows]] == before) & (cells.stuck[cells_sub[rows]] < 0)
        cells.mode[i, cells_sub[rows][graze]] = h1[i, sub[rows][graze]] > 0


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
    turned = idx[motion_codes(cells.excursion[idx]) == 1]
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


@dataclass(frozen=True)
class Agreement:
    """How a basin map compares with a reference on some cells."""

    cells: int                   # cells compared
    agreeing: int
    disagreeing: list            # (row, column) of each disagreeing cell, row = dphi0 index
    on_boundary: list            # for each disagreeing cell: has it a neighbour of the other class?

    @property
    def fraction(self):
        return self.agreeing / self.cells if self.cells else math.nan


@dataclass
class BasinMap:
    """A basin map: the outcome of every cell of a grid of initial conditions.

    Attributes
    ----------
    phi0 : ndarray, shape (N,)
        Initial crank angles [rad] (columns).
    dphi0 : ndarray, shape (M,)
        Initial crank speeds [rad/s] (rows).
    outcome : ndarray of int, shape (M, N)
        0 = oscillation, 1 = full rotation (``labels``).
    t_end : float
    step : float
        Step of the batch integrator [s].
    labels : dict
        Code -> outcome name, from :data:`closedloop.slider_crank.MOTIONS`.
    excursion, decided_at, stuck_at : ndarray, shape (M, N)
        Largest |phi - phi0| [rad], the time the crank turned 2 pi, the first
        time the slider stuck (nan where it did not happen).
    wall_time, cpu_time : float
        Seconds of the whole computation (cpu_time summed over worker processes).
    workers : int
    evaluations : int
        Vectorised evaluations of the accelerations (per worker, summed).
    cell_evaluations : int
        Evaluations counted per cell.
    max_constraint_error : float
        Largest |f| (32) at the final states.
    reading : str
    version : str
    motions : BasinMotions or None
        phi(t) of every cell, if the map was asked for them (``basin_map(..., motions=...)``);
        the cells were then integrated to ``t_end``, and ``excursion`` is that of the whole run.
    """

    phi0: np.ndarray
    dphi0: np.ndarray
    outcome: np.ndarray
    t_end: float
    step: float
    labels: dict
    excursion: np.ndarray
    decided_at: np.ndarray
    stuck_at: np.ndarray
    wall_time: float
    cpu_time: float
    workers: int
    evaluations: int
    cell_evaluations: int
    max_constraint_error: float
    reading: str
    version: str = field(default="")
    motions: BasinMotions = None

    @property
    def fraction_rotating(self):
        """The share of cells that turn a full revolution."""
        return float(np.mean(self.outcome == 1))

    def outcome_at(self, phi0, dphi0):
        """The outcome code of the sample nearest to (phi0, dphi0)."""
        return int(self.outcome[_cell_index(self.dphi0, dphi0), _cell_index(self.phi0, phi0)])

    def as_json(self):
        """The JSON object written by ``closedloop basin --json``."""
        return {
            "phi0": self.phi0.tolist(), "dphi0": self.dphi0.tolist(), "t_end": self.t_end,
            "outcome": self.outcome.tolist(), "labels": {str(k): v for k, v in self.labels.items()},
            "version": self.version, "cpu_s": self.cpu_time, "wall_s": self.wall_time,
            "step": self.step, "reading": self.reading, "workers": self.workers,
        }


def _cell_index(values, value):
    """Index of the sample nearest to ``value``."""
    return int(np.argmin(np.abs(np.asarray(values) - value)))


def _check_grid(phi0_values, dphi0_values):
    """The slider-crank map's grids: increasing, finite, within initial_state's ANGLE_LIMIT and SPEED_LIMIT."""
    arrays = []
    for name, values, limit, unit in (("phi0", phi0_values, ANGLE_LIMIT, "rad"),
                                      ("dphi0", dphi0_values, SPEED_LIMIT, "rad/s")):
        values = finite_array(name, values)
        if values.size == 0:
            raise InputError(f"{name}: need a non-empty list of values")
        if values.size > 1 and np.any(np.diff(values) <= 0):
            raise InputError(f"{name}: values must increase strictly")
        if np.max(np.abs(values)) > limit:
            raise InputError(f"{name}: values must lie within -{limit:g} .. {limit:g} {unit}, got up to "
                             f"{np.max(np.abs(values)):g}")
        arrays.append(values)
    return arrays


def _chunk(args):
    """One worker's share of the grid (top level, so that multiprocessing can pickle it)."""
    reading, phi0, dphi0, t_end, step, samples = args
    start = time.process_time()
    result = integrate_outcomes(slider_crank_system(reading=reading), phi0, dphi0, t_end, step,
                                initial_state=slider_crank_initial_state, sample_times=samples)
    return result, time.process_time() - start


def basin_map(phi0_values, dphi0_values, t_end=20.0, *, step=DEFAULT_STEP, reading=None, workers=1,
              progress=None, motions=None):
    """Classify every cell of a grid of initial conditions: full rotation or oscillation.

    Parameters
    ----------
    phi0_values : array_like, shape (N,)
        Initial crank angles [rad], increasing (see :func:`grid_values`).
    dphi0_values : array_like, shape (M,)
        Initial crank speeds [rad/s], increasing.
    t_end : float, optional
        Length of each run [s], > 0; default 20 s, as the paper's figures.
    step : float, optional
        Step of the batch integrator [s]; default :data:`DEFAULT_STEP`.
    reading : str, optional
        Reading of the paper's data; default the one that reproduces the paper.
    workers : int, optional
        Processes to use (the grid is split into that many chunks); 1 runs in this process.
    progress : callable, optional
        ``progress(fraction)``, called as the work advances (only with one worker
        it follows time; with several, it follows finished chunks).
    motions : float, optional
        Also keep each cell's motion phi(t), sampled from 0 to ``t_end`` about every ``motions``
        seconds: at the spacing ``t_end / round(t_end / motions)``, which divides ``t_end`` evenly
        (the map's ``motions``, a :class:`BasinMotions`), from the same integration:
        every cell then runs to ``t_end`` instead of leaving the batch once it has turned 2 pi,
        which changes no outcome.  Default None: no motions.

    Returns
    -------
    BasinMap
    """
    phi0_values, dphi0_values = _check_grid(phi0_values, dphi0_values)
    reading = get_reading(DEFAULT_READING if reading is None else reading).name
    _check_time(t_end, step, _step_bound(slider_crank_system(reading=reading), dphi0_values)[2])
    samples = None if motions is None else _motion_times(t_end, motions)
    if not (isinstance(workers, (int, np.integer)) and 1 <= workers <= (os.cpu_count() or 1) * 4):
        raise InputError(f"workers: must be an integer from 1 to {(os.cpu_count() or 1) * 4}, got {workers!r}")
    _check_work(phi0_values.size * dphi0_values.size, t_end, step)     # the whole map, before it is split
    phi_grid, dphi_grid = np.meshgrid(phi0_values, dphi0_values)
    phi_flat, dphi_flat = phi_grid.ravel(), dphi_grid.ravel()
    wall, cpu = time.perf_counter(), time.process_time()
    if workers == 1:
        results = [(integrate_outcomes(slider_crank_system(reading=reading), phi_flat, dphi_flat, t_end, step,
                                       progress=progress, initial_state=slider_crank_initial_state,
                                       sample_times=samples), 0.0)]
        order = [np.arange(phi_flat.size)]
    else:
        order = [np.arange(phi_flat.size)[j::workers] for j in range(workers)]   # interleaved: equal work
        tasks = [(reading, phi_flat[o], dphi_flat[o], t_end, step, samples) for o in order]
        # derive once, and find the forcing's period (sympy, a second or so), before the workers fork
        rule.forcing_period(slider_crank_system(reading=reading))
        with multiprocessing.get_context("fork").Pool(workers) as pool:
            results = []
            for done, item in enumerate(pool.imap(_chunk, tasks), 1):
                results.append(item)
                if progress is not None:
                    progress(done / workers)
    size = phi_flat.size
    fields_ = {name: np.empty(size) for name in ("outcome", "excursion", "decided_at", "stuck_at")}
    for o, (result, _) in zip(order, results):
        fields_["outcome"][o] = result.codes
        fields_["excursion"][o] = result.excursion
        fields_["decided_at"][o] = result.decided_at
        fields_["stuck_at"][o] = result.stuck_at
    shape = (dphi0_values.size, phi0_values.size)
    kept = None
    if samples is not None:
        phi = np.empty((size, samples.size))
        for o, (result, _) in zip(order, results):
            phi[o] = result.motion
        kept = BasinMotions(times=samples, phi=phi.reshape(shape + (samples.size,)),
                            excursion=fields_["excursion"].reshape(shape).copy(), step=results[0][0].step)
    return BasinMap(
        phi0=phi0_values, dphi0=dphi0_values, outcome=fields_["outcome"].astype(int).reshape(shape),
        t_end=float(t_end), step=results[0][0].step, labels=dict(enumerate(MOTIONS)),
        excursion=fields_["excursion"].reshape(shape), decided_at=fields_["decided_at"].reshape(shape),
        stuck_at=fields_["stuck_at"].reshape(shape), wall_time=time.perf_counter() - wall,
        cpu_time=time.process_time() - cpu + sum(c for _, c in results), workers=workers,
        evaluations=sum(r.evaluations for r, _ in results),
        cell_evaluations=sum(r.cell_evaluations for r, _ in results),
        max_constraint_error=max(r.max_constraint_error for r, _ in results), reading=reading,
        version=__version__, motions=kept,
    )


#: Settings of the per-trajectory reference of :func:`reference_outcomes`.
#: The redundant coordinates with their accelerations in closed form and the compiled DOP853: another
#: formulation and another integrator than the map's (minimal coordinates, fixed-step RK4), and the
#: library's fastest adaptive route.  The reference before it, Minimal with solve_ivp's DOP853 at the same
#: tolerance, took 12.3 s for the 120-cell grid of the tests; this takes 0.9 s, with the same outcome in
#: every cell.
REFERENCE = {"formulation": ClosedForm(), "method": "ode.dop853", "rtol": 1e-10, "atol": 1e-10}


def reference_outcome(system, phi0, dphi0, t_end=20.0, *, initial_state=None):
    """One cell classified by :func:`closedloop.simulate` (:data:`REFERENCE`: ClosedForm, ode.dop853,
    rtol = atol = 1e-10).

    The run stops once the excursion ``|q - q0|`` of the independent coordinate
    (phi for the slider-crank) passes 2 pi + 0.5 rad (the outcome is then
    settled); :func:`~closedloop.slider_crank.motion_codes`, the rule of
    :func:`~closedloop.slider_crank.classify_motion`, decides on it.

    Parameters
    ----------
    system : System
        A one-degree-of-freedom system.
    phi0, dphi0 : float
        The cell's start: the independent coordinate [rad] and its rate [rad/s].
    t_end : float
    initial_state : callable, optional, keyword only
        As for :func:`integrate_outcomes`.

    Returns
    -------
    int
        The outcome code, an index of :data:`~closedloop.slider_crank.MOTIONS`.
    """
    initial_state = _start_rule(system, initial_state)
    q = int(system.q_index[0])
    limit = 2.0 * math.pi + 0.5
    result = simulate(system, initial_state(system, float(phi0), float(dphi0)), t_end,
                      stop_when=lambda t, s, sd: abs(s[q] - phi0) - limit, **REFERENCE)
    return int(motion_codes(np.max(np.abs(result.s[q] - phi0))))


def reference_outcomes(phi0_values, dphi0_values, t_end=20.0, cells=None, reading=None):
    """The reference outcome of grid cells, one :func:`closedloop.simulate` run per cell.

    Parameters
    ----------
    phi0_values, dphi0_values : array_like
        The grid, as for :func:`basin_map`.
    t_end : float
    cells : iterable of (row, column), optional
        Only these cells (row indexes dphi0, column indexes phi0); default all.
    reading : str, optional

    Returns
    -------
    ndarray of int, shape (M, N)
        Outcome codes; -1 where a cell was not computed.
    """
    phi0_values, dphi0_values = _check_grid(phi0_values, dphi0_values)
    system = slider_crank_system(reading=DEFAULT_READING if reading is None else reading)
    out = np.full((dphi0_values.size, phi0_values.size), -1)
    if cells is None:
        cells = [(i, j) for i in range(dphi0_values.size) for j in range(phi0_values.size)]
    for i, j in cells:
        out[i, j] = reference_outcome(system, phi0_values[j], dphi0_values[i], t_end)
    return out


def boundary_cells(outcome):
    """Cells with a neighbour (left, right, up or down) of the other outcome: the basin boundary.

    Cells marked -1 (not computed) are no one's neighbour.

    Returns
    -------
    ndarray of bool, same shape as ``outcome``
    """
    outcome = np.asarray(outcome)
    boundary = np.zeros(outcome.shape, bool)
    for axis in (0, 1):
        a = np.moveaxis(outcome, axis, 0)
        b = np.moveaxis(boundary, axis, 0)
        differ = (a[1:] != a[:-1]) & (a[1:] >= 0) & (a[:-1] >= 0)
        b[1:] |= differ
        b[:-1] |= differ
    return boundary


def compare_outcomes(outcome, reference, boundary_from=None):
    """Compare a map with a reference on the cells the reference computed (>= 0).

    A disagreeing cell is "on the boundary" if it has a neighbour of the other
    class in ``boundary_from`` (default: the reference itself when it is a
    full grid, else the map).
    """
    outcome, reference = np.asarray(outcome), np.asarray(reference)
    computed = reference >= 0
    if boundary_from is None:
        boundary_from = reference if np.all(computed) else outcome
    boundary = boundary_cells(boundary_from)
    wrong = computed & (outcome != reference)
    rows, cols = np.nonzero(wrong)
    cells = [(int(i), int(j)) for i, j in zip(rows, cols)]
    return Agreement(cells=int(computed.sum()), agreeing=int((computed & ~wrong).sum()), disagreeing=cells,
                     on_boundary=[bool(boundary[i, j]) for i, j in cells])
