"""One integration segment with the compiled DOP853 of scipy.integrate.ode.

``solve_ivp(method="DOP853")`` runs Dormand and Prince's 8(5,3) pair with its
step loop in Python, which costs about 4 µs per right-hand-side evaluation
before the right-hand side itself is called.  ``scipy.integrate.ode`` wraps
Hairer and Wanner's own DOP853 code [Hairer, Nørsett, Wanner, *Solving ODEs I*,
section II.10], the same pair with a compiled step loop: only the right-hand
side runs in Python.  That code has no events and no dense output, so this
module adds what :func:`closedloop.simulate` needs from a segment:

- after every accepted step (the ``solout`` callback) the switching functions
  are evaluated at the step's end; a sign change in the watched direction stops
  the integration, as solve_ivp's terminal events do;
- the crossing is then located: a cubic Hermite interpolant over the step
  (from the states and right-hand sides at both ends) gives a first estimate,
  the step is redone from its start to that time with the same code, and
  Newton steps in time (each a second-order Taylor step of the state, which
  is exact to round-off for the microsecond corrections left) put the
  switching function at zero.

Requested output times become step ends (the code stops there), so no output
is interpolated.  The method is selected by ``simulate(..., method="ode.dop853")``.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass

import numpy as np
from scipy.integrate import ode

from .. import hermite
from ..errors import IntegrationError
from ..methods import COMPILED_METHOD

__all__ = ["METHOD", "ALLOWED_OPTIONS", "integrate_segment", "Segment"]

#: The method name simulate() uses for this integrator.
METHOD = COMPILED_METHOD
#: The solver options this integrator takes (everything else is refused before integrating).
ALLOWED_OPTIONS = ("max_step", "first_step", "nsteps")
#: Steps allowed in one call of the compiled code before it gives up (per segment piece).
DEFAULT_NSTEPS = 200_000
_RETURN_CODES = {
    -1: "the input is not consistent",
    -2: "more steps were needed than allowed (nsteps); the problem may be stiff",
    -3: "the step size became too small",
    -4: "the problem is probably stiff",
}


@dataclass
class Segment:
    """What one call of :func:`integrate_segment` produced.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Output times (every step end, or the requested output times) up to the stop.
    y : ndarray, shape (m, N)
    t_stop : float
    y_stop : ndarray, shape (m,)
    event : int or None
        Index of the switching function that stopped the segment, None at t_end.
    nfev : int
    last_step : float
        The last accepted step size: a good first step for the next segment.
    steps : list of float
        Every accepted step size, in order (not counting the steps redone to
        locate the switch).
    step_ends : ndarray, shape (m, K)
        The state at the start, at every accepted step end, and at the switch
        where the segment stopped, for checks along the path that output
        times alone would miss.
    step_times : ndarray, shape (K,)
        The times of ``step_ends``.
    """

    t: np.ndarray
    y: np.ndarray
    t_stop: float
    y_stop: np.ndarray
    event: int | None
    nfev: int
    last_step: float
    steps: list
    step_ends: np.ndarray
    step_times: np.ndarray


class BudgetExceeded(Exception):
    """The right-hand side was called ``max_nfev`` times; ``t`` is where."""

    def __init__(self, t):
        super().__init__(t)
        self.t = t


def integrate_segment(rhs, t0, y0, t_end, *, rtol, atol, switching, directions, outputs=None,
                      first_step=0.0, max_step=0.0, nsteps=DEFAULT_NSTEPS, max_nfev=math.inf):
    """Integrate ``y' = rhs(t, y)`` from ``t0`` to ``t_end`` or the first switch.

    Parameters
    ----------
    rhs : callable
        ``rhs(t, y) -> sequence`` of length ``y0.size``.
    t0, t_end : float
    y0 : ndarray
    rtol, atol : float
    switching : callable
        ``switching(t, y) -> sequence of float``: the functions watched for a zero.
    directions : sequence of float
        For each switching function: -1 to stop where it falls through zero,
        +1 where it rises, 0 for both (as solve_ivp's ``event.direction``).
    outputs : ndarray, optional
        Output times in ``[t0, t_end]``; default: every step end.
    first_step, max_step : float, optional
        0 lets the code choose.
    nsteps : int, optional
        Steps allowed per call of the compiled code.
    max_nfev : float, optional
        Right-hand-side evaluations allowed; beyond, :class:`BudgetExceeded`.

    Returns
    -------
    Segment

    Raises
    ------
    IntegrationError
        If the code fails (the message names the time and the reason).
    """
    y0 = np.asarray(y0, dtype=float)
    failure = []                            # an exception raised inside the compiled code's callbacks
    counted, evaluations = _counting(rhs, max_nfev, failure)
    directions = tuple(float(d) for d in directions)
    watch = _StepWatch(switching, directions, t0, y0, first_step, keep_steps=outputs is None, failure=failure)
    if outputs is None:
        targets, wanted = [t_end], set()
    else:
        wanted = {float(t) for t in outputs}
        targets = sorted(t for t in wanted | {float(t_end)} if t > t0)
        if t0 not in wanted:
            watch.times, watch.states = [], []
    with warnings.catch_warnings():          # the code's warnings become the errors raised below
        warnings.simplefilter("ignore", UserWarning)
        for target in targets:
            if target <= watch.last_t:
                continue
            solver = ode(counted).set_integrator("dop853", rtol=rtol, atol=atol, nsteps=nsteps,
                                                 first_step=min(watch.last_step, target - watch.last_t),
                                                 max_step=max_step)
            solver.set_solout(watch.solout)
            solver.set_initial_value(watch.last_y, watch.last_t)
            solver.integrate(target)
            if failure:
                raise _with_path(failure[0], watch, getattr(failure[0], "t", None))
            if watch.hit is not None:
                return _stopped_at_switch(watch, counted, switching, directions, rtol, atol, failure, evaluations,
                                          outputs is None, y0.size)
            code = solver.get_return_code()
            if code < 0:
                error = IntegrationError(
                    f"ode.dop853 failed at t = {solver.t:.6g} s: {_RETURN_CODES.get(code, f'code {code}')}. "
                    "Try an implicit method (Radau, BDF), looser tolerances, or smaller Baumgarte gains")
                error.return_code, error.t = code, float(solver.t)
                raise _with_path(error, watch)
            watch.last_t, watch.last_y = target, np.array(solver.y, dtype=float)
            if target in wanted:
                watch.times.append(target)
                watch.states.append(watch.last_y.copy())
    return Segment(np.array(watch.times), np.array(watch.states).reshape(len(watch.times), y0.size).T, t_end,
                   watch.last_y.copy(), None, evaluations(), watch.last_step, watch.steps, np.array(watch.ends).T,
                   np.array(watch.end_times))


def _with_path(error, watch, failed_at=None):
    """``error`` carrying the step ends reached so far (``path_times``, ``path_states``) and the time of
    the call that failed (``failed_at``), for the caller's checks."""
    error.path_times, error.path_states = np.array(watch.end_times), np.array(watch.ends).T
    error.failed_at = failed_at
    return error


def _counting(rhs, max_nfev, failure):
    """``(counted, evaluations)``: rhs that counts its calls (and stops at max_nfev), and the count.

    The compiled caller cannot propagate an exception: a failing call stores it
    in ``failure`` and returns NaN, and the segment re-raises it.
    """
    count = 0

    if max_nfev == math.inf:
        def counted(t, y):
            nonlocal count
            count += 1
            try:
                return rhs(t, y)
            except Exception as error:
                failure.append(_failed_at(t, error))
                return [math.nan] * y.size
    else:
        def counted(t, y):
            nonlocal count
            count += 1
            try:
                if count > max_nfev:
                    raise BudgetExceeded(t)
                return rhs(t, y)
            except Exception as error:
                failure.append(_failed_at(t, error))
                return [math.nan] * y.size

    return counted, lambda: count


def _failed_at(t, error):
    """The error of a right-hand side that failed at time ``t`` (its attribute ``t``, for the caller's checks);
    an arithmetic overflow becomes an IntegrationError that says so."""
    if isinstance(error, (OverflowError, FloatingPointError)):
        detail = error.args[-1] if error.args else type(error).__name__
        error = IntegrationError(
            f"{COMPILED_METHOD} failed at t = {t:.6g} s: the right-hand side overflowed ({detail}), the "
            "accelerations are beyond the range of floating-point numbers. Try an implicit method (Radau, BDF), "
            "tighter tolerances, or smaller Baumgarte gains")
    error.t = t
    return error


class _StepWatch:
    """The ``solout`` callback: records every accepted step and stops at the first watched sign change.

    ``last_t, last_y, last_g``: the last accepted step end and its switching
    values; ``last_step``: its step size; ``hit``: ``(t, y, g)`` of the step that
    crossed, or None; ``times, states``: the outputs; ``steps, ends``: every step.
    """

    def __init__(self, switching, directions, t0, y0, first_step, keep_steps, failure):
        self.switching, self.directions, self.failure, self.keep_steps = switching, directions, failure, keep_steps
        self.last_t, self.last_y, self.last_g = t0, y0.copy(), list(switching(t0, y0))
        self.last_step, self.hit = first_step, None
        self.times, self.states = [t0], [y0.copy()]
        self.steps, self.ends, self.end_times = [], [y0.copy()], [t0]

    def solout(self, t, y):
        if self.failure:
            return -1
        if t <= self.last_t:                 # the call at the start point
            return 0
        g = list(self.switching(t, y))
        for b, a, direction in zip(self.last_g, g, self.directions):
            if a != b and ((direction >= 0 and b <= 0.0 <= a) or (direction <= 0 and b >= 0.0 >= a)):
                self.hit = (t, y.copy(), g)
                return -1
        self.last_step = t - self.last_t
        self.steps.append(self.last_step)
        y = y.copy()                         # one copy serves all three lists: none is changed in place
        self.ends.append(y)
        self.end_times.append(t)
        self.last_t, self.last_y, self.last_g = t, y, g
        if self.keep_steps:
            self.times.append(t)
            self.states.append(y)
        return 0


def _stopped_at_switch(watch, counted, switching, directions, rtol, atol, failure, evaluations, every_step, size):
    """The Segment of a segment stopped by a switch: locate the crossing in the step that crossed."""
    t_event, y_event, event = _locate(counted, switching, (watch.last_t, watch.last_y, watch.last_g), watch.hit,
                                      directions, rtol, atol, failure)
    if failure:
        raise failure[0]
    if every_step:                          # solve_ivp's convention: the event ends sol.t
        watch.times.append(t_event)
        watch.states.append(y_event)
    watch.ends.append(y_event)
    watch.end_times.append(t_event)
    return Segment(np.array(watch.times), np.array(watch.states).reshape(len(watch.times), size).T, t_event,
                   y_event, event, evaluations(), watch.last_step, watch.steps, np.array(watch.ends).T,
                   np.array(watch.end_times))


def _locate(rhs, switching, start, hit, directions, rtol, atol, failure):
    """The first zero inside the step that stopped the code: ``(t, y, index)``.

    Each switching function g_i is approximated over the step by the cubic
    Hermite interpolant of its values and its rates dg_i/dt at both ends (the
    rates along the flow, by a forward difference), which costs two right-hand
    sides and two more switching evaluations, and needs no interpolated states.
    """
    ta, ya, ga = start
    tb, yb, gb = hit
    span = tb - ta
    eps = 1e-7 * max(abs(span), 1e-9)
    fa, fb = np.asarray(rhs(ta, ya)), np.asarray(rhs(tb, yb))
    rates_a = [(after - before) / eps for before, after in zip(ga, switching(ta + eps, ya + eps * fa))]
    rates_b = [(after - before) / eps for before, after in zip(gb, switching(tb + eps, yb + eps * fb))]
    best = None
    for i, d in enumerate(directions):
        before, after = ga[i], gb[i]
        crossed = (before <= 0.0 <= after and d >= 0) or (before >= 0.0 >= after and d <= 0)
        if not crossed or before == after:
            continue
        root = ta + span * hermite.first_root(before, after, span * rates_a[i], span * rates_b[i])
        if best is None or root < best[0]:
            best = (root, i)
    t_star, i = best
    # The state at the estimate, integrated (not interpolated), then Newton in time.
    t, y = t_star, _redo(rhs, ta, ya, t_star, rtol, atol) if t_star > ta else ya.copy()
    rate, delta = None, math.inf
    for _ in range(8):
        if failure:
            break
        g = switching(t, y)[i]
        if g == 0.0:
            break
        if abs(delta) <= 1e-5:              # after a short correction the last rate still serves
            delta = -g / rate
            if abs(delta) <= 4e-16 * max(1.0, abs(t)):
                break
            f = np.asarray(rhs(t, y))
        else:                               # first, or after a redo: the rate at this t
            f = np.asarray(rhs(t, y))
            rate = (switching(t + eps, y + eps * f)[i] - g) / eps
            if rate == 0.0 or not math.isfinite(rate):
                break
            delta = -g / rate
            if abs(delta) <= 4e-16 * max(1.0, abs(t)):
                break
        if abs(delta) <= 1e-5 and ta < t + delta:
            y = y + 0.5 * delta * (f + np.asarray(rhs(t + delta, y + delta * f)))   # Heun: O(delta^3)
            t = t + delta
        else:
            t = min(max(t + delta, ta), tb)
            y = _redo(rhs, ta, ya, t, rtol, atol)
            delta = math.inf
    return t, y, i


def _redo(rhs, ta, ya, t, rtol, atol):
    """The state at t, integrated from the step start ``(ta, ya)`` by the same code."""
    solver = ode(rhs).set_integrator("dop853", rtol=rtol, atol=atol, nsteps=DEFAULT_NSTEPS,
                                     first_step=t - ta)
    solver.set_initial_value(ya, ta)
    y = solver.integrate(t)                 # inside integrate_segment's catch_warnings
    if solver.get_return_code() < 0:
        raise IntegrationError(
            f"ode.dop853 failed at t = {solver.t:.6g} s while locating a switch: "
            f"{_RETURN_CODES.get(solver.get_return_code())}. Try a solve_ivp method"
        )
    return np.array(y, dtype=float)
