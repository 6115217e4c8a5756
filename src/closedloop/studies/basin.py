"""The basin map: which initial conditions (phi0, phi0') end in full rotation, which in a swing.

The paper's conclusion (section 5) says that the motion of the slider-crank depends on its
initial conditions and shows four of them.  This study classifies a whole grid of them:
:func:`basin_map` integrates every cell with the engine's batch integrator
(:mod:`closedloop.simulation.batch`, minimal coordinates, fixed-step Runge-Kutta, the switching
rule of :func:`closedloop.simulate`), here or on any :class:`concurrent.futures.Executor`
(:mod:`closedloop.simulation.batch_pool`), and calls a cell a full rotation where its crank
turned 2 pi away from its start (:func:`~closedloop.slider_crank.motion_codes`).

:func:`reference_outcomes` classifies cells one by one with :func:`closedloop.simulate`
(ClosedForm, ode.dop853, rtol = 1e-10: :data:`REFERENCE`) for the agreement check, and
:func:`boundary_cells`, :func:`compare_outcomes` say where a map and a reference differ.
"""

from __future__ import annotations

import functools
import math
import time
from dataclasses import dataclass, field

import numpy as np

from .. import __version__
from ..errors import InputError
from ..formulations import ClosedForm
from ..simulation import simulate
from ..simulation.batch import DEFAULT_STEP, FULL_TURN, BatchOutcome, full_turn, integrate_batch
from ..simulation.batch_limits import MAX_STEPS, check_span, check_work, step_bound
from ..simulation.batch_pool import integrate_parts
from ..slider_crank import (ANGLE_LIMIT, DEFAULT_READING, MOTIONS, SPEED_LIMIT, SliderCrankSystem, get_reading,
                            slider_crank_system)
from ..slider_crank import initial_state as slider_crank_initial_state
from ..validation import finite_array, finite_number, positive_integer, positive_number

__all__ = ["BasinMap", "BasinMotions", "basin_map", "integrate_outcomes", "reference_outcome", "reference_outcomes",
           "boundary_cells", "compare_outcomes", "Agreement", "BatchOutcome", "DEFAULT_STEP", "MAX_STEPS",
           "grid_values", "motion_times"]


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

def motion_times(t_end, sample):
    """Times from 0 to t_end [s], at the spacing nearest ``sample`` (> 0 s) that divides t_end evenly
    (``t_end / round(t_end / sample)``), at which a map's motions are kept.

    Raises
    ------
    InputError
        For a t_end or sample that is not a positive number, or a sample longer than t_end.
    """
    t_end = positive_number("t_end", t_end, unit="s")
    sample = positive_number("motions", sample, unit="s")
    if sample > t_end:
        raise InputError(f"motions: the sample spacing must be <= t_end = {t_end:g} s, got {sample:g} s")
    return np.linspace(0.0, t_end, int(round(t_end / sample)) + 1)

def integrate_outcomes(system, phi0, dphi0, t_end=20.0, step=DEFAULT_STEP, progress=None, finish_early=True, *,
                       initial_state=None, sample_times=None):
    """:func:`closedloop.simulation.batch.integrate_batch`, with the slider-crank's start by default.

    Parameters
    ----------
    system : System
        A one-degree-of-freedom system.
    phi0, dphi0 : array_like, shape (K,)
        Starts of the independent coordinate [rad] and its rate [rad/s] (for the
        slider-crank, the crank angle phi and speed phi').
    t_end, step, progress, finish_early, sample_times :
        As for :func:`~closedloop.simulation.batch.integrate_batch`.
    initial_state : callable, optional, keyword only
        ``initial_state(system, q0, qd0)``, a cell's consistent start; default, for a
        :class:`~closedloop.slider_crank.SliderCrankSystem`,
        :func:`closedloop.slider_crank.initial_state`; any other system must pass one.

    Returns
    -------
    BatchOutcome
        ``codes`` indexes :data:`~closedloop.slider_crank.MOTIONS`.

    Raises
    ------
    InputError
        Where ``initial_state`` is missing for a system other than the slider-crank, and as
        :func:`~closedloop.simulation.batch.integrate_batch` raises.
    """
    return integrate_batch(system, phi0, dphi0, t_end, step, initial_state=_start_rule(system, initial_state),
                           progress=progress, finish_early=finish_early, sample_times=sample_times)


def _start_rule(system, initial_state):
    """The function that assembles a cell's start: the caller's, or the slider-crank's by default."""
    if initial_state is None:
        if not isinstance(system, SliderCrankSystem):
            raise InputError("initial_state: needed for a system other than the slider-crank: a function "
                             "initial_state(system, q0, qd0) that returns a consistent InitialState")
        return slider_crank_initial_state
    return initial_state


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


def basin_map(phi0_values, dphi0_values, t_end=20.0, *, step=DEFAULT_STEP, reading=None, workers=1,
              progress=None, motions=None, executor=None):
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
        How many parts the grid is split into (cell j in part ``j % workers``), each run
        by a worker process of this machine, or submitted to ``executor``; 1 (and no
        executor) runs in this process.  The same ``workers`` gives the same map to the
        bit wherever its parts run.
    progress : callable, optional
        ``progress(fraction)``, called as the work advances (in this process it follows
        time; in parts, it follows finished parts).
    motions : float, optional
        Also keep each cell's motion phi(t), sampled from 0 to ``t_end`` about every ``motions``
        seconds: at the spacing ``t_end / round(t_end / motions)``, which divides ``t_end`` evenly
        (the map's ``motions``, a :class:`BasinMotions`), from the same integration:
        every cell then runs to ``t_end`` instead of leaving the batch once it has turned 2 pi,
        which changes no outcome.  Default None: no motions.
    executor : concurrent.futures.Executor, optional
        Where the parts run, e.g. ``client.get_executor()`` of a Dask ``distributed``
        client for a cluster; default the local worker processes, which end with this
        process however it ends.

    Returns
    -------
    BasinMap

    Raises
    ------
    InputError
        For grids that are not increasing or leave the slider-crank's ranges, a step too
        coarse or too fine, a map of too many cell-steps, a ``workers`` that is not a
        positive integer, an ``executor`` that is not an Executor.
    """
    phi0_values, dphi0_values = _check_grid(phi0_values, dphi0_values)
    reading = get_reading(DEFAULT_READING if reading is None else reading).name
    check_span(t_end, step, step_bound(slider_crank_system(reading=reading), dphi0_values)[2])
    samples = None if motions is None else motion_times(t_end, motions)
    check_work(phi0_values.size * dphi0_values.size, t_end, step)     # the whole map, before it is split
    phi_grid, dphi_grid = np.meshgrid(phi0_values, dphi0_values)
    wall, cpu = time.perf_counter(), time.process_time()
    result, parts_cpu = integrate_parts(functools.partial(slider_crank_system, reading=reading), phi_grid.ravel(),
                                        dphi_grid.ravel(), t_end, step, initial_state=slider_crank_initial_state,
                                        parts=workers, executor=executor, sample_times=samples, progress=progress)
    shape = (dphi0_values.size, phi0_values.size)
    kept = None
    if samples is not None:
        kept = BasinMotions(times=samples, phi=result.motion.reshape(shape + (samples.size,)),
                            excursion=result.excursion.reshape(shape).copy(), step=result.step)
    return BasinMap(
        phi0=phi0_values, dphi0=dphi0_values, outcome=result.codes.reshape(shape), t_end=float(t_end),
        step=result.step, labels=dict(enumerate(MOTIONS)), excursion=result.excursion.reshape(shape),
        decided_at=result.decided_at.reshape(shape), stuck_at=result.stuck_at.reshape(shape),
        wall_time=time.perf_counter() - wall, cpu_time=time.process_time() - cpu + parts_cpu, workers=workers,
        evaluations=result.evaluations, cell_evaluations=result.cell_evaluations,
        max_constraint_error=result.max_constraint_error, reading=reading, version=__version__, motions=kept,
    )


#: Settings of the per-trajectory reference of :func:`reference_outcomes`.
#: The redundant coordinates with their accelerations in closed form and the compiled DOP853: another
#: formulation and another integrator than the map's (minimal coordinates, fixed-step RK4), and the
#: library's fastest adaptive route.
REFERENCE = {"formulation": ClosedForm(), "method": "ode.dop853", "rtol": 1e-10, "atol": 1e-10}


def reference_outcome(system, phi0, dphi0, t_end=20.0, *, initial_state=None):
    """One cell classified by :func:`closedloop.simulate` (:data:`REFERENCE`: ClosedForm, ode.dop853,
    rtol = atol = 1e-10).

    The run stops once the excursion ``|q - q0|`` of the independent coordinate
    (phi for the slider-crank) passes 2 pi + 0.5 rad (the outcome is then
    settled); :func:`~closedloop.simulation.batch.full_turn`, the batch
    integrator's rule (and :func:`~closedloop.slider_crank.classify_motion`'s), decides on it.

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
        1 where the cell turned a full revolution, else 0 (an index of
        :data:`~closedloop.slider_crank.MOTIONS`).
    """
    initial_state = _start_rule(system, initial_state)
    q = int(system.q_index[0])
    limit = FULL_TURN + 0.5
    result = simulate(system, initial_state(system, float(phi0), float(dphi0)), t_end,
                      stop_when=lambda t, s, sd: abs(s[q] - phi0) - limit, **REFERENCE)
    return int(full_turn(np.max(np.abs(result.s[q] - phi0))))


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
