"""DOP853's continuous extension of order 7, and the outputs it gives inside the compiled code's steps.

The compiled DOP853 (:mod:`~closedloop.simulation.dop853_code`) steps from ``t0`` to the end
of a segment without stopping at the requested output times, and scipy's ``ode`` gives no
dense output.  The outputs inside an accepted step come from Dormand and Prince's continuous
extension of order 7 (Hairer's ``contd8`` [Hairer, Nørsett, Wanner, *Solving ODEs I*, section
II.6], the dense output of ``solve_ivp(method="DOP853")``).  The code calls the right-hand side
for every stage and ``solout`` after every accepted step, so the stages of that step are the
last twelve calls: :class:`DenseOutputs` records them and checks that they rebuild the code's
step end to round-off (else recomputes them, :func:`step_stages`); only the three extra stages of
the extension (:func:`continuous_extensions`) are new right-hand sides, and only in the steps
that hold an output time.  The interpolant is :func:`interpolate`.
"""

from __future__ import annotations

import math
from types import SimpleNamespace
from typing import NamedTuple

import numpy as np

from ..errors import IntegrationError
from ..loading import first_use
from . import dop853_code
from .dop853_code import IFACTOR

__all__ = ["DenseOutputs", "HeldStep", "evaluate_held_steps", "step_stages", "continuous_extension",
           "continuous_extensions", "interpolate", "STAGES"]

#: The stages of a DOP853 step (k_1 .. k_12); with f at the step end and the extension's three, 16.
STAGES = 12


@first_use
def _tableau():
    """DOP853's coefficients (:func:`~closedloop.simulation.dop853_code.coefficients`), in the forms used here.

    ``A``, ``B``, ``C`` of the step, ``abs_B`` = |B|, ``extra_stages``: ``(row, a_row[:row], c)``
    of the extension's three extra stages, and ``F_of_K`` (7, 16), Hairer's ``contd8`` as
    ``F = h F_of_K K + (the terms in yb - ya)``: ``F0 = yb - ya``, ``F1 = h k_1 - F0``,
    ``F2 = 2 F0 - h (k_1 + k_13)``, ``F3..F6 = h D K``.
    """
    c = dop853_code.coefficients()
    if c.stages != STAGES:                                  # pragma: no cover - another method under that name
        raise ImportError(f"scipy's DOP853 has {c.stages} stages, not {STAGES}")
    F_of_K = np.zeros((7, STAGES + 4))
    F_of_K[1, 0] = 1.0
    F_of_K[2, [0, STAGES]] = -1.0
    F_of_K[3:] = c.D
    extra = [(s, a[:s].copy(), cs) for s, (a, cs) in enumerate(zip(c.A_EXTRA, c.C_EXTRA), start=STAGES + 1)]
    return SimpleNamespace(A=c.A, B=c.B, C=c.C, abs_B=np.abs(c.B), extra_stages=extra, F_of_K=F_of_K)


class DenseOutputs:
    """The requested output times of a segment, from DOP853's continuous extension of the accepted steps.

    The compiled code's right-hand side (counted by :mod:`~closedloop.simulation.dop853`)
    records every call's time and values in ``calls``; the calls since the last accepted
    step are kept.  When ``solout`` reports an
    accepted step from ``ta`` to ``tb``, its last twelve calls are the eleven
    stages at ``ta + c_i h`` (i = 2..12) and f at the new step end (the code's
    FSAL evaluation); the step's first stage is f at ``ta``, the previous step's
    last call.  Calls of rejected steps come before them and are skipped.  An output
    time at a step end is the code's state there.  A step that holds output times
    inside it is kept (its ends and its recorded stages: a few references, no
    arithmetic), and when the segment ends :meth:`outputs` evaluates all of them
    at once (:func:`evaluate_held_steps`): the stages are checked (their times, and
    the step end ``ya + h sum b_i k_i`` they give against the code's, to round-off),
    the three extra stages of the extension are computed, and the interpolant is
    evaluated at each step's output times.  A step whose check fails (a code that
    calls in another order, a step whose calls were not all recorded) has its stages
    recomputed from ``(ta, ya, h)`` and checked the same way.  Per step that holds
    outputs this costs the three right-hand sides and a few Python operations; the
    arithmetic is done in whole arrays, over all such steps or all outputs.

    The calls are recorded only where they may be needed: after an accepted step
    of size h ending at ``tb``, recording stays on for the next step if the next
    output time lies within :data:`_LOOKAHEAD` h of ``tb`` (far enough for the two
    steps that follow, whose first one gives f at the start of the second), and
    is off otherwise, so that sparse outputs (one time in a long run) cost no
    bookkeeping per call.

    Parameters
    ----------
    rhs : callable
        The counted right-hand side, for the extra stages.
    calls : closedloop.simulation.dop853.Calls
        Where ``rhs`` records its calls.
    times : array_like
        The requested output times; those outside ``[t0, t_end]`` are ignored.
    t0, y0 : float, ndarray
        The segment's start (an output if ``t0`` is requested).
    t_end : float
    record : callable, optional
        ``record(on)`` turns the recording of the calls into ``calls`` on or off.
    first_step : float, optional
        The code's first step (0: its own choice, unknown), which no accepted first step exceeds.
    increasing : bool, optional
        True: ``times`` are known to increase strictly, and are not checked again.
    """

    def __init__(self, rhs, calls, times, t0, y0, t_end, record=None, first_step=0.0, increasing=False):
        times = np.asarray(times, dtype=float)
        if not increasing and (times.ndim != 1 or (times.size > 1 and np.any(times[1:] <= times[:-1]))):
            times = np.unique(times)
        self.rhs, self.size = rhs, y0.size
        # the times in [t0, t_end] of the increasing times
        self.times = times[np.searchsorted(times, t0, side="left"):np.searchsorted(times, t_end, side="right")]
        self.next = 0                       # index of the first time not yet output
        self.next_time = float(self.times[0]) if self.times.size else math.inf   # that time, or inf
        self.record = record if record is not None else (lambda on: None)
        self.record(not first_step > 0.0 or self.next_time - t0 <= _LOOKAHEAD * first_step)
        self.calls = calls                  # the calls since the last accepted step
        self.f_start = None                 # f at the start of the current step (a list), or None
        self.crossing = None                # the calls and f_start of the step that crossed a switch
        self.held = []                      # HeldStep of the steps that hold output times inside them
        # their 13 recorded stages (f at ta, then the last twelve calls), one step after another, n floats a
        # stage; zeros for a step whose calls were not all recorded (its stages are recomputed)
        self.stages = []
        self.missing = [0.0] * ((STAGES + 1) * self.size)
        self.known = []                     # (start, stop, y): the outputs start..stop-1 are the state y
        if self.times.size and self.times[0] == t0:
            self._known(1, y0)

    def start(self, t0):
        """At the code's ``solout`` call at the start point: its first call was f at ``t0``."""
        calls, n = self.calls, self.size
        if calls.times and calls.times[0] == t0 and len(calls.values) >= n:
            self.f_start = calls.values[:n]
        calls.clear()

    def step(self, ta, ya, tb, yb):
        """An accepted step from ``(ta, ya)`` to ``(tb, yb)``: the requested times in ``(ta, tb]`` are its."""
        calls, f_start, n = self.calls, self.f_start, self.size
        times, values = calls.last(STAGES, n)
        self.f_start = values[-n:] if values is not None and times and times[-1] == tb else None
        if tb >= self.next_time:
            self._hold(ta, ya, tb, yb, f_start, times, values, int(self.times.searchsorted(tb, "right")))
        calls.clear()
        self.record(self.next_time - tb <= _LOOKAHEAD * (tb - ta))

    def crossed(self):
        """``solout`` stopped the code at a step that crossed a switch: keep that step's calls."""
        self.crossing = (*self.calls.last(STAGES, self.size), self.f_start)

    def before_switch(self, ta, ya, tb, yb, t_event):
        """The requested times in ``(ta, t_event)`` are those of the step that crossed, ``(ta, ya)`` to ``(tb, yb)``."""
        stop = int(np.searchsorted(self.times, t_event, side="left"))
        if stop > self.next:
            times, values, f_start = self.crossing
            self._hold(ta, ya, tb, yb, f_start, times, values, stop)

    def finish(self, y_end):
        """At t_end: any time left lies beyond the last step end by round-off, where the state is ``y_end``."""
        if self.next < self.times.size:
            self._known(self.times.size - self.next, y_end)

    def outputs(self, size):
        """``(times, states)``: the output times so far and the states there, shape (size, N)."""
        count = self.next
        states = np.empty((size, count))
        for start, stop, y in self.known:
            states[:, start:stop] = y[:, None]
        if self.held:
            self.record(False)
            held, stages, self.held, self.stages = self.held, self.stages, [], []
            evaluate_held_steps(self.rhs, held, stages, self.times, states)
        return self.times[:count].copy(), states

    def _hold(self, ta, ya, tb, yb, f_start, times, values, stop):
        """The output times ``next .. stop-1`` lie in the step ``(ta, ya)`` to ``(tb, yb)``: keep it, with its
        last recorded calls (``times``, and their ``values``, or None if some call did not give n values)."""
        start, inside = self.next, stop if self.times[stop - 1] != tb else stop - 1
        if inside > start:
            complete = f_start is not None and values is not None and len(times) == STAGES
            if complete:
                self.stages.extend(f_start)
                self.stages.extend(values)
            else:
                self.stages.extend(self.missing)
            self.held.append(HeldStep(ta, ya, tb, yb, complete, times[0] if times else math.nan,
                                       times[-1] if times else math.nan, start, inside))
        self.next = inside
        if stop > inside:                   # an output at the step end: the code's own state
            self._known(1, yb)

    def _known(self, count, y):
        self.known.append((self.next, self.next + count, np.asarray(y, dtype=float)))
        self.next += count
        self.next_time = float(self.times[self.next]) if self.next < self.times.size else math.inf


class HeldStep(NamedTuple):
    """An accepted step that holds output times: its ends, its recorded calls, which outputs it holds."""

    ta: float
    ya: np.ndarray
    tb: float
    yb: np.ndarray
    complete: bool           # f at ta and its last twelve calls were recorded (in DenseOutputs.stages)
    first_call: float        # the time of the first of its last twelve recorded calls (the stage 2), or nan
    last_call: float         # the time of its last recorded call (f at tb), or nan
    start: int               # the outputs start .. stop-1 lie inside it
    stop: int


def evaluate_held_steps(rhs, held, stages, times, states):
    """Write into ``states`` the outputs inside the ``held`` steps (:class:`HeldStep`), all at once.

    ``stages`` holds their 13 recorded stages, one step after another (:attr:`DenseOutputs.stages`).

    Their stages come from the recorded calls where those pass the check of
    :func:`_rebuilds_step_ends`, else are recomputed (:func:`step_stages`) and checked
    again; then :func:`continuous_extensions` and one product per step with the basis of
    :func:`_basis` at all outputs.
    """
    count, size = len(held), states.shape[0]
    ta, tb, h, ya, yb = _held_ends(held)
    K = np.empty((STAGES + 4, count, size))               # stage, step, component
    complete = np.array([step.complete for step in held])
    K[:STAGES + 1] = np.fromiter(stages, float, len(stages)).reshape(count, STAGES + 1, size).transpose(1, 0, 2)
    first_call = np.array([step.first_call for step in held])
    last_call = np.array([step.last_call for step in held])
    checked = (complete
               & (np.abs(first_call - (ta + _tableau().C[1] * h)) <= 1e-9 * np.abs(h) + 1e-15 * np.maximum(np.abs(ta), np.abs(tb)))
               & (last_call == tb) & _rebuilds_step_ends(ya, h, K, yb, tb))
    for k in np.flatnonzero(~checked).tolist():
        # f at ta too: a recorded f may be an array that the rhs reuses
        K[:, k] = step_stages(rhs, ta[k], ya[k], h[k], rhs(ta[k], ya[k]), t_end=tb[k], y_end=yb[k])
        if not _rebuilds_step_ends(ya[k:k + 1], h[k:k + 1], K[:, k:k + 1], yb[k:k + 1], tb[k:k + 1])[0]:
            error = IntegrationError(
                f"ode.dop853 failed at t = {ta[k]:.6g} s: the stages of the step to t = {tb[k]:.6g} s, recomputed, "
                "do not give the compiled code's step end, so no output inside it can be interpolated; "
                "use a solve_ivp method, or no t_eval")
            error.t = float(ta[k])
            raise error
    # [F; ya] of every step, as (step, component, 8): one product with the basis per step
    coefficients = np.concatenate((continuous_extensions(rhs, ta, ya, tb, yb, K), ya[None]), axis=0)
    coefficients = coefficients.transpose(1, 2, 0).copy()
    counts = [step.stop - step.start for step in held]
    x = np.concatenate([times[step.start:step.stop] for step in held])       # the held outputs, in order
    x -= np.repeat(ta, counts)
    x /= np.repeat(h, counts)                                                # fractions of their steps
    # The basis a group of steps at a time (the steps from k on that hold <= _GROUP_OUTPUTS outputs, or
    # one step): a few numpy calls per group, and no basis of 8 rows by all outputs at once (a 10 000-output
    # run would allocate, and fault in, 640 kB for it).
    k = first = 0
    while k < count:
        end, total = k + 1, counts[k]
        while end < count and total + counts[end] <= _GROUP_OUTPUTS:
            total += counts[end]
            end += 1
        basis, column = _basis(x[first:first + total]), 0
        for j in range(k, end):
            step = held[j]
            np.matmul(coefficients[j], basis[:, column:column + counts[j]], out=states[:, step.start:step.stop])
            column += counts[j]
        k, first = end, first + total


def _held_ends(held):
    """``(ta, tb, h, ya, yb)`` of the held steps: arrays (S,) and (S, n)."""
    ta = np.array([step.ta for step in held])
    tb = np.array([step.tb for step in held])
    return ta, tb, tb - ta, np.array([step.ya for step in held]), np.array([step.yb for step in held])


_EPS = np.finfo(float).eps
#: How far ahead of a step end, in units of that step's size h, the next output time makes
#: DenseOutputs record the calls of the next step.  The compiled code lets a step grow at most
#: IFACTOR = 6 times (:mod:`~closedloop.simulation.dop853_code`) and stretches the last step to t_end by
#: at most 1 %, so the two steps that follow end before 6.06 h + 6.06^2 h = 42.8 h (here with a 20 %
#: margin); a step that grew more than that would only have its stages recomputed (13 more right-hand
#: sides), never a wrong output.
_LOOKAHEAD = 1.2 * (1.01 * IFACTOR) * (1.0 + 1.01 * IFACTOR)
#: Outputs whose basis (:func:`_basis`, 8 rows) is computed at once: 8 x 2000 floats, 125 kB, under
#: glibc's threshold (128 kB) for allocating with mmap, whose pages are faulted in anew every time.
_GROUP_OUTPUTS = 2000
#: A step end rebuilt from the stages may differ from the code's by this many units of round-off
#: of the sum ``ya + h sum b_i k_i`` (the code sums in another order, and its h differs from
#: ``tb - ta`` by round-off in tb).
_ROUND_OFF_UNITS = 64.0


def step_stages(rhs, ta, ya, h, f_start, t_end=None, y_end=None):
    """The stages of one DOP853 step, recomputed: ``K`` of shape (16, n).

    Rows 0 to 11 are the stages k_1 .. k_12 of the step of size ``h`` from
    ``(ta, ya)`` (k_1 = ``f_start`` = f(ta, ya)); row 12 is f at the step end,
    ``(t_end, y_end)`` if given (the compiled code's), else ``(ta + h, ya + h sum b_i k_i)``.
    Rows 13 to 15 are left for :func:`continuous_extension`.  Costs 12 right-hand sides.

    Parameters
    ----------
    rhs : callable
    ta : float
    ya : ndarray, shape (n,)
    h : float
    f_start : array_like, shape (n,)
    t_end : float, optional
    y_end : ndarray, optional
    """
    tableau = _tableau()
    A, B, C = tableau.A, tableau.B, tableau.C
    K = np.empty((STAGES + 4, ya.size))
    K[0] = f_start
    for s in range(1, STAGES):
        K[s] = rhs(ta + C[s] * h, ya + h * (A[s, :s] @ K[:s]))
    if y_end is None:
        t_end, y_end = ta + h, ya + h * (B @ K[:STAGES])
    K[STAGES] = rhs(t_end, y_end)
    return K


def continuous_extension(rhs, ta, ya, tb, yb, stages):
    """The coefficients ``F`` (7, n) of DOP853's continuous extension over one step (Hairer's ``contd8``).

    Computes the three extra stages (three right-hand sides) from the step's 13
    ``stages`` (:func:`step_stages`), into their rows 13 to 15; the interpolant
    is :func:`interpolate`.
    It is of order 7, and it passes through ``ya`` and ``yb`` with the slopes
    f(ta, ya) and f(tb, yb).  One step of :func:`continuous_extensions`.

    Parameters
    ----------
    rhs : callable
    ta, tb : float
        The step's start and end.
    ya, yb : ndarray, shape (n,)
    stages : ndarray, shape (16, n)
    """
    K = stages[:, None]
    return continuous_extensions(rhs, np.array([ta]), np.asarray(ya, dtype=float)[None], np.array([tb]),
                                 np.asarray(yb, dtype=float)[None], K)[:, 0]


def continuous_extensions(rhs, ta, ya, tb, yb, stages):
    """:func:`continuous_extension` of S steps at once: ``F`` of shape (7, S, n).

    ``ta``, ``tb`` of shape (S,), ``ya``, ``yb`` of shape (S, n), ``stages`` of shape
    (16, S, n) (rows 13 to 15 are filled here: three right-hand sides per step).
    ``F0 = yb - ya``, ``F1 = h k_1 - F0``, ``F2 = 2 F0 - h (k_1 + k_13)``, ``F3..F6 = h D K``.
    """
    tableau = _tableau()
    h = tb - ta
    h_column = h[:, None]
    K = stages
    for s, a, c in tableau.extra_stages:                       # K[:s] as stage x (step, component): one product
        arguments = ya + h_column * (a @ K[:s].reshape(s, -1)).reshape(ya.shape)
        row = K[s]
        for k, t in enumerate((ta + c * h).tolist()):
            row[k] = rhs(t, arguments[k])           # one at a time: a right-hand side may reuse its array
    F = (tableau.F_of_K @ K.reshape(K.shape[0], -1)).reshape(7, *ya.shape) * h_column
    change = yb - ya
    F[0] += change
    F[1] -= change
    F[2] += 2.0 * change
    return F


def _basis(x):
    """The products ``b_j(x) = x, x (1 - x), x^2 (1 - x), ...`` (rows 0 to 6) and a row of ones: (8, m).

    ``y(x) = ya + x (F0 + (1 - x) (F1 + x (F2 + (1 - x) (F3 + x (F4 + (1 - x) (F5 + x F6))))))``
    is ``[F; ya]^T`` times this, summed as ``ya + sum_j F_j b_j(x)`` (no cancellation in the
    products: the same round-off as the nested form, all outputs at once).
    """
    products = np.empty((8, x.size))
    rest = 1.0 - x
    products[0] = x
    for j in range(1, 7):
        np.multiply(products[j - 1], rest if j % 2 else x, out=products[j])
    products[7] = 1.0
    return products


def interpolate(F, ya, x):
    """The continuous extension (coefficients ``F`` of :func:`continuous_extension`) at fractions ``x`` of
    the step: ndarray (n, m)."""
    return np.vstack((F, ya)).T @ _basis(np.atleast_1d(np.asarray(x, dtype=float)))


def _rebuilds_step_ends(ya, h, stages, yb, tb):
    """Whether ``ya + h sum b_i k_i`` is the code's step end ``yb`` to round-off, for S steps at once:
    boolean array (S,) (``ya``, ``yb`` of shape (S, n), ``h``, ``tb`` of shape (S,), ``stages`` (16, S, n))."""
    tableau = _tableau()
    K = stages[:STAGES].reshape(STAGES, -1)
    # |h sum b_i k_i - (yb - ya)| against the round-off of the sum and of h (up to |tb| eps |sum b_i k_i|)
    scale = np.abs(ya) + (np.abs(h) + np.abs(tb))[:, None] * (tableau.abs_B @ np.abs(K)).reshape(ya.shape)
    return (np.abs(ya + h[:, None] * (tableau.B @ K).reshape(ya.shape) - yb) <= _ROUND_OFF_UNITS * _EPS * scale).all(axis=1)
