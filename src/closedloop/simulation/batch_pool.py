"""A batch split into parts: run here, on worker processes of this machine, or on any executor.

:func:`integrate_parts` cuts the cells of a batch into interleaved parts (cell j goes to
part ``j % parts``, so that every part holds fast and slow cells alike), integrates each
part with :func:`~closedloop.simulation.batch.integrate_batch`, and puts the outcomes
back in the cells' order.  A part is a task that carries only data and functions named
at a module's top level (``make_system``, ``initial_state``), so that it can be sent to
another process or another machine: a :class:`concurrent.futures.Executor` such as a
``ProcessPoolExecutor`` or a Dask ``distributed`` client's ``get_executor()``.

The same parts give the same numbers wherever they run: the cells of a part share their
steps, so a map split into the same number of parts is the same to the bit on one core,
on local processes or on a cluster.

Without an executor, the parts run on forked worker processes of this machine.  Each
worker ends with its parent, even one killed by SIGKILL: on Linux the kernel sends the
worker SIGKILL when its parent dies (``prctl(PR_SET_PDEATHSIG)``, set by the pool's
initializer, which then checks that the parent has not died already); elsewhere a
thread in the worker looks at its parent's pid twice a second.
"""

from __future__ import annotations

import ctypes
import multiprocessing
import os
import signal
import sys
import threading
import time
from concurrent.futures import Executor, as_completed

import numpy as np

from ..errors import InputError
from . import switching as rule
from .batch import BatchOutcome, integrate_batch

__all__ = ["integrate_parts", "part_indices", "MAX_PARTS"]

#: The most parts a batch may be split into.
MAX_PARTS = 100_000
#: prctl's option that sets the signal a process gets when its parent dies (linux/prctl.h).
_PR_SET_PDEATHSIG = 1
#: How often a worker without prctl looks at its parent [s].
_WATCH_INTERVAL = 0.5


def part_indices(size, parts):
    """The cells of each part: part j holds cells j, j + parts, j + 2 parts, ... (empty parts left out)."""
    return [index for index in (np.arange(size)[j::parts] for j in range(parts)) if index.size]


def _part(task):
    """One part of a batch, in whatever process runs it: ``(BatchOutcome, its CPU seconds)``."""
    make_system, q0, qd0, t_end, step, initial_state, sample_times = task
    start = time.process_time()
    outcome = integrate_batch(make_system(), q0, qd0, t_end, step, initial_state=initial_state,
                              sample_times=sample_times)
    return outcome, time.process_time() - start


def _die_with_parent(parent):
    """The local pool's initializer: this worker ends when the process ``parent`` does, SIGKILL included."""
    if sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            watched = libc.prctl(_PR_SET_PDEATHSIG, int(signal.SIGKILL), 0, 0, 0) == 0
        except (OSError, AttributeError):
            watched = False
    else:
        watched = False
    if os.getppid() != parent:               # the parent died before the request took effect
        os._exit(1)
    if not watched:
        threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()


def _watch_parent(parent):
    while os.getppid() == parent:
        time.sleep(_WATCH_INTERVAL)
    os._exit(1)


def _run(tasks, workers, executor, progress):
    """The parts' results in the tasks' order, and whether they ran in this process."""
    if executor is not None:
        futures = [executor.submit(_part, task) for task in tasks]
        try:
            for done, _ in enumerate(as_completed(futures), 1):
                if progress is not None:
                    progress(done / len(futures))
            return [future.result() for future in futures]
        finally:
            for future in futures:
                future.cancel()
    with multiprocessing.get_context("fork").Pool(workers, initializer=_die_with_parent,
                                                  initargs=(os.getpid(),)) as pool:
        results = []
        for done, item in enumerate(pool.imap(_part, tasks), 1):
            results.append(item)
            if progress is not None:
                progress(done / len(tasks))
        return results


def integrate_parts(make_system, q0, qd0, t_end, step, *, initial_state, parts=1, executor=None,
                    sample_times=None, progress=None):
    """:func:`~closedloop.simulation.batch.integrate_batch` of K cells, split into parts.

    Parameters
    ----------
    make_system : callable
        ``make_system()`` returns the System; a function at a module's top level (or a
        ``functools.partial`` of one), so that a part can be sent to another process.
    q0, qd0 : ndarray, shape (K,)
    t_end, step : float
    initial_state : callable, keyword only
        As for :func:`~closedloop.simulation.batch.integrate_batch`, at a module's top level.
    parts : int, optional
        How many parts; with no ``executor``, also how many worker processes (1 runs
        the batch in this process).
    executor : concurrent.futures.Executor, optional
        Where the parts run, each one task (``executor.submit``); default the local
        worker processes.
    sample_times : array_like, optional
    progress : callable, optional
        ``progress(fraction)``: of the time span in this process, else of the parts done.

    Returns
    -------
    outcome : BatchOutcome
        Every cell in the order of ``q0``.
    cpu_time : float
        CPU seconds of the parts run elsewhere, summed (0 for a batch run here).

    Raises
    ------
    InputError
        For a ``parts`` that is not an integer from 1 to :data:`MAX_PARTS` (with an executor)
        or to four per core (without), or an ``executor`` that is not a
        :class:`concurrent.futures.Executor`.
    """
    most = MAX_PARTS if executor is not None else (os.cpu_count() or 1) * 4     # local: one process a part
    if not (isinstance(parts, (int, np.integer)) and not isinstance(parts, bool) and 1 <= parts <= most):
        raise InputError(f"workers: must be an integer from 1 to {most}, got {parts!r}")
    if executor is not None and not isinstance(executor, Executor):
        raise InputError(f"executor: must be a concurrent.futures.Executor, got {type(executor).__name__}")
    q0, qd0 = np.asarray(q0, dtype=float).ravel(), np.asarray(qd0, dtype=float).ravel()
    if parts == 1 and executor is None:
        return integrate_batch(make_system(), q0, qd0, t_end, step, initial_state=initial_state,
                               sample_times=sample_times, progress=progress), 0.0
    order = part_indices(q0.size, parts)
    tasks = [(make_system, q0[o], qd0[o], t_end, step, initial_state, sample_times) for o in order]
    if executor is None:
        rule.forcing_period(make_system())   # sympy's work done once, before the workers fork
    results = _run(tasks, parts, executor, progress)
    return _merged(order, [outcome for outcome, _ in results], q0.size), sum(cpu for _, cpu in results)


def _merged(order, outcomes, size):
    """One BatchOutcome of the parts' outcomes, each cell back in its place."""
    def joined(name):
        first = getattr(outcomes[0], name)
        if first is None:
            return None
        out = np.empty((size,) + first.shape[1:], dtype=first.dtype)
        for o, outcome in zip(order, outcomes):
            out[o] = getattr(outcome, name)
        return out

    cells = ("codes", "excursion", "decided_at", "stuck_at", "released_at", "final_phi", "final_dphi",
             "switch_events", "motion")
    return BatchOutcome(**{name: joined(name) for name in cells},
                        evaluations=sum(o.evaluations for o in outcomes),
                        cell_evaluations=sum(o.cell_evaluations for o in outcomes),
                        max_constraint_error=max(o.max_constraint_error for o in outcomes), step=outcomes[0].step)
