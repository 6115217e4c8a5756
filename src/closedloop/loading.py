"""Modules loaded on first use, and the process time their loading took.

The library imports scipy.integrate (0.3 to 0.5 s of process time, with scipy.linalg, scipy.optimize,
scipy.sparse and scipy.special), scipy.linalg (0.2 to 0.3 s: LAPACK's dgesv, QR), scipy.optimize (the search for a
change point) and scipy's compiled DOP853 only when something needs them, and loads generated code
once per system (:mod:`closedloop.codecache`), so that the command line answers without the ones
it does not use.
Such a load is the process's, once: it is not part of the run during which it happens.  A run's
``cpu_time`` (:func:`closedloop.simulate`) is the difference of two readings of :func:`run_clock`,
which leaves the loads made between them out, so that the first run of a process costs what the
same run costs after it.

The module imports nothing from closedloop, so any module may use it.
"""

from __future__ import annotations

import contextlib
import functools
import time

__all__ = ["first_use", "one_time", "load_time", "run_clock"]

#: [process time spent in one_time blocks so far, blocks open now]
_state = [0.0, 0]


def load_time():
    """Process time [s] this process has spent in :func:`one_time` blocks (the loaders of :func:`first_use`)."""
    return _state[0]


def run_clock():
    """Process time [s] less :func:`load_time`: the difference of two readings is the CPU time of what
    ran between them, the loads made on first use left out."""
    return time.process_time() - _state[0]


@contextlib.contextmanager
def one_time():
    """Count the process time of the ``with`` block in :func:`load_time` (once, if such blocks nest): for
    work done once per process, or once per system, inside a run (a module's import, generated code)."""
    start = time.process_time()
    _state[1] += 1
    try:
        yield
    finally:
        _state[1] -= 1
        if _state[1] == 0:                  # the outermost block counts the time of those inside it
            _state[0] += time.process_time() - start


def first_use(load):
    """``load()`` run at the first call only, inside :func:`one_time`, its result kept for every later call.

    Parameters
    ----------
    load : callable
        ``load() -> object``, without arguments: an import, and what it gives.
    """

    @functools.wraps(load)
    def loaded():
        with one_time():
            return load()

    return functools.cache(loaded)
