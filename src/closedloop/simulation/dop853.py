"""One integration segment with the compiled DOP853 of scipy.integrate.ode, stopped at a switch.

``scipy.integrate.ode`` runs Hairer and Wanner's DOP853 code [Hairer, Nørsett, Wanner,
*Solving ODEs I*, section II.10], the pair of ``solve_ivp(method="DOP853")`` with a compiled
step loop (:mod:`~closedloop.simulation.dop853_code`): only the right-hand side runs in Python.
The code has no events, so this module adds them:

- after every accepted step (the ``solout`` callback) the switching functions are evaluated
  at the step's end; a sign change in the watched direction stops the code, as solve_ivp's
  terminal events do;
- the crossing is then located: a cubic Hermite interpolant of the switching functions over
  the step gives a first estimate, the step is redone from its start to that time by the same
  code, and Newton steps in time put the switching function at zero.

Requested output times do not stop the code: the outputs inside an accepted step come from
the continuous extension (:mod:`~closedloop.simulation.dop853_dense`).  The code runs with
scipy's settings but two: the retry of a rejected step (:data:`REJECTION_FACTOR`) and the
stabilised step size control (:data:`STEP_CONTROL_BETA`).  The method is selected by
``simulate(..., method="ode.dop853")``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import hermite
from ..errors import IntegrationError
from ..methods import COMPILED_METHOD
from . import dop853_code
from .dop853_dense import DenseOutputs
from .switching import CHOSEN_SIDE

__all__ = ["METHOD", "ALLOWED_OPTIONS", "REJECTION_FACTOR", "STEP_CONTROL_BETA", "integrate_segment", "Segment",
           "BudgetExceeded"]

#: The method name simulate() uses for this integrator.
METHOD = COMPILED_METHOD
#: The solver options this integrator takes (everything else is refused before integrating).
ALLOWED_OPTIONS = ("max_step", "first_step", "nsteps")
#: Steps allowed in one call of the compiled code before it gives up (per segment piece).
DEFAULT_NSTEPS = 200_000
#: The compiled code's ``fac1`` here (scipy's ``dfactor``, default 0.3): the ratio of the retry to a
#: rejected step.  Hairer's DOP853 retries a step rejected with error estimate err > 1 at
#: ``h max(fac1, safe / err^(1/8))`` [Hairer, Nørsett, Wanner, section II.4]; scipy's C translation
#: (``dop.c``, ``dp86co``) retries at ``fac1 h`` whatever err is, so 0.6 is a retry that passes for
#: err < 0.6^-8 = 60 (with 0.3 each rejection cost two steps of 0.3 h).  In a scipy whose code follows
#: Hairer's rule, 0.6 is only its floor.
REJECTION_FACTOR = 0.6
#: The compiled code's ``beta`` here (scipy's default 0): the weight of the last accepted step's
#: error estimate in the next step size, ``h min(fac2, max(fac1, safe err_old^beta / err^(1/8 - beta/5)))``
#: [Hairer and Wanner, section IV.2, "stabilized step size control"], which damps the cycle of a step
#: that grows, is rejected and grows again; 0.04 is Hairer's value for DOPRI5.  What it saves on the
#: slider-crank: ``benchmarks/dop853_settings.md``.
STEP_CONTROL_BETA = 0.04
_RETURN_CODES = {
    -1: "the input is not consistent",
    -2: "more step attempts were needed in one segment than nsteps = {nsteps} allows (rejected steps count "
        "too); the problem may be stiff, or nsteps too small",
    -3: "the step size became too small",
    -4: "the problem is probably stiff",
}


def _reason(code, nsteps):
    """What the compiled code's return ``code`` (< 0) means, for a call that allowed ``nsteps`` step attempts."""
    return _RETURN_CODES.get(code, f"code {code}").format(nsteps=nsteps)


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
        Every accepted step size, in order: the step that crossed the switch
        too, whole (it ends beyond the switch), but not the steps redone to
        locate the switch.  Step ``k`` begins at ``step_times[k]``.
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
                      outputs_increasing=False, first_step=0.0, max_step=0.0, nsteps=DEFAULT_NSTEPS,
                      max_nfev=math.inf, max_steps=math.inf, on_step=None):
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
        Output times in ``[t0, t_end]`` (others are ignored), evaluated with
        DOP853's continuous extension inside the accepted steps: they change
        neither the steps nor the end state; default: every step end.
    outputs_increasing : bool, optional
        True when the caller has checked that ``outputs`` increase strictly (as
        :func:`closedloop.simulate` does once for all segments); else they are
        checked here, and sorted if they do not.
    first_step, max_step : float, optional
        0 lets the code choose.
    nsteps : int, optional
        Steps allowed per call of the compiled code (its ``nmax``, which counts
        rejected steps too and lets one more through).
    max_steps : float, optional
        Accepted steps allowed before ``t_end``; beyond, an IntegrationError with
        ``return_code`` -2, as the compiled code's own for ``nsteps``, and with
        ``max_steps_reached`` True, which tells the two apart.
    max_nfev : float, optional
        Right-hand-side evaluations allowed; beyond, :class:`BudgetExceeded`.
    on_step : callable, optional
        ``on_step(t, y)`` after every accepted step that ends before the switch (the
        caller's checks along the path); an exception it raises stops the code, and is
        raised here.

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
    calls = None if outputs is None else Calls()  # the calls, for the stages of the steps
    counted, evaluations, record = _counting(rhs, max_nfev, failure, calls)
    directions = tuple(float(d) for d in directions)
    dense = None if outputs is None else DenseOutputs(counted, calls, outputs, t0, y0, t_end, record,
                                                       first_step=min(first_step, t_end - t0),
                                                       increasing=outputs_increasing)
    watch = _StepWatch(switching, directions, t0, y0, first_step, failure=failure, dense=dense,
                       max_steps=max_steps, t_end=t_end, on_step=on_step)
    if t_end > t0:
        t_code, y_code, code = dop853_code.dopri853(      # scipy's ode(counted) "dop853", but for fac1
            counted, t0, y0, t_end, rtol=rtol, atol=atol, nsteps=nsteps,
            first_step=min(watch.last_step, t_end - t0), max_step=max_step, solout=watch.solout,
            dfactor=REJECTION_FACTOR, beta=STEP_CONTROL_BETA)
        if failure:
            raise _with_failed_at(failure[0], getattr(failure[0], "t", None))
        if watch.hit is not None:
            return _stopped_at_switch(watch, counted, switching, directions, rtol, atol, failure, evaluations,
                                      y0.size)
        if code < 0:
            error = IntegrationError(
                f"ode.dop853 failed at t = {t_code:.6g} s: {_reason(code, nsteps)}. "
                "Try an implicit method (Radau, BDF), looser tolerances, or smaller Baumgarte gains")
            error.return_code, error.t, error.max_steps_reached = code, float(t_code), False
            error.last_call = _LATEST[0]           # where the failing attempts evaluated the right-hand side
            raise _with_failed_at(error)
        watch.last_t, watch.last_y = t_end, np.array(y_code, dtype=float)
    if dense is not None:
        dense.finish(watch.last_y)          # an output at t_end beyond the last step end by round-off
    return watch.segment(t_end, watch.last_y.copy(), None, evaluations, y0.size)


def _with_failed_at(error, failed_at=None):
    """``error`` carrying the time of the call that failed (``failed_at``, None for a failure at a step end),
    for the caller's checks along the path."""
    error.failed_at = failed_at
    return error


class Calls:
    """The right-hand side's calls recorded by :func:`_counting`: their times, and their values one call
    after another (``n`` floats a call), copied when the call returns, so that a right-hand side may reuse
    its array."""

    __slots__ = ("times", "values")

    def __init__(self):
        self.times, self.values = [], []

    def clear(self):
        self.times.clear()
        self.values.clear()

    def last(self, count, n):
        """``(times, values)`` of the last ``count`` calls; ``values`` is None if some call did not give ``n``
        values (a failed call, or a right-hand side of another size)."""
        times, values = self.times, self.values
        whole = len(values) == n * len(times)
        return times[-count:], values[-count * n:] if whole else None


def _counting(rhs, max_nfev, failure, calls=None):
    """``(counted, evaluations, record)``: rhs that counts its calls (and stops at max_nfev), the count, and
    ``record(on)``, which turns the recording of the calls on or off.

    The compiled caller cannot propagate an exception: a failing call stores it
    in ``failure`` and returns NaN, and the segment re-raises it.  With a :class:`Calls`
    ``calls``, every call made while recording is on (at first it is) appends its time
    and its values to it (for :class:`~closedloop.simulation.dop853_dense.DenseOutputs`); without one, ``record`` does nothing.
    """
    count = 0
    recording = calls is not None
    if recording:
        add_time, add_values = calls.times.append, calls.values.extend
    latest = _LATEST                                # the time of the last call, for a failure's message
    latest[0] = math.nan

    def record(on):
        nonlocal recording
        recording = on and calls is not None

    def counted(t, y):
        nonlocal count
        count += 1
        latest[0] = t
        try:
            if count > max_nfev:
                raise BudgetExceeded(t)
            f = rhs(t, y)
        except Exception as error:
            failure.append(_failed_at(t, error))
            f = [math.nan] * y.size
        if recording:
            add_time(t)
            add_values(f)
        return f

    return counted, lambda: count, record


#: The time of the last right-hand side of the segment under way (one list: no allocation per call).
_LATEST = [math.nan]


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
    crossed, or None; ``steps, ends, end_times``: every step (the ends are also the
    outputs without ``dense``); ``dense``: the requested outputs, or None.  The
    ``max_steps``-th accepted step that ends before ``t_end`` (or a step beyond it) stops
    the code with an IntegrationError in ``failure``; so does an exception of ``on_step(t, y)``,
    called after every accepted step that does not cross.
    """

    def __init__(self, switching, directions, t0, y0, first_step, failure, dense=None, max_steps=math.inf,
                 t_end=math.inf, on_step=None):
        self.switching, self.directions, self.failure = switching, directions, failure
        self.max_steps, self.t_end, self.on_step = max_steps, t_end, on_step
        # an exact zero at the start counts as on the side the segment runs on (switching.on_chosen_side): a
        # crossing in the first step is then located there, not at t0
        self.last_t, self.last_y = t0, y0.copy()
        self.last_g = [value if value != 0.0 else (CHOSEN_SIDE if direction < 0 else -CHOSEN_SIDE)
                       for value, direction in zip(switching(t0, y0), directions)]
        self.last_step, self.hit, self.dense = first_step, None, dense
        self.steps, self.ends, self.end_times = [], [self.last_y], [t0]

    def solout(self, t, y):
        if self.failure:
            return -1
        if t <= self.last_t:                 # the call at the start point
            if self.dense is not None:
                self.dense.start(t)
            return 0
        try:
            g = list(self.switching(t, y))
        except Exception as error:           # the compiled caller cannot propagate it
            self.failure.append(error)
            return -1
        for b, a, direction in zip(self.last_g, g, self.directions):
            if a != b and ((direction >= 0 and b <= 0.0 <= a) or (direction <= 0 and b >= 0.0 >= a)):
                self.hit = (t, y.copy(), g)
                self.steps.append(t - self.last_t)  # an accepted step: it counts, as solve_ivp's do
                if len(self.steps) > self.max_steps:
                    return self._out_of_steps(t)
                if self.dense is not None:
                    self.dense.crossed()
                return -1
        ta, ya = self.last_t, self.last_y
        self.last_step = t - self.last_t
        self.steps.append(self.last_step)
        if len(self.steps) > self.max_steps or (len(self.steps) == self.max_steps and t < self.t_end):
            return self._out_of_steps(t)
        y = y.copy()                         # one copy serves both: neither is changed in place
        self.ends.append(y)
        self.end_times.append(t)
        self.last_t, self.last_y, self.last_g = t, y, g
        if self.on_step is not None:
            try:
                self.on_step(t, y)
            except Exception as error:       # the compiled caller cannot propagate it
                self.failure.append(error)
                return -1
        if self.dense is not None:
            try:
                self.dense.step(ta, ya, t, y)
            except Exception as error:       # the compiled caller cannot propagate it
                self.failure.append(error)
            if self.failure:
                return -1
        return 0

    def _out_of_steps(self, t):
        """Stop the code: the accepted steps reached ``max_steps`` at ``t`` with more to go."""
        error = IntegrationError(f"ode.dop853 reached max_steps = {self.max_steps} at t = {t:.6g} s")
        error.return_code, error.t, error.max_steps_reached = -2, t, True
        self.failure.append(error)
        return -1

    def segment(self, t_stop, y_stop, event, evaluations, size):
        """The Segment that ends at ``(t_stop, y_stop)``: its outputs are the requested times, or the step ends
        (solve_ivp's convention: with the switch, if one stopped it).  ``evaluations()`` is the count of
        right-hand sides, read after the outputs are evaluated (they may call it)."""
        step_times, step_ends = np.array(self.end_times), np.array(self.ends).reshape(len(self.ends), size).T
        t, y = (step_times, step_ends) if self.dense is None else self.dense.outputs(size)
        if self.failure:                     # a right-hand side of the outputs' extra stages failed
            raise _with_failed_at(self.failure[0], getattr(self.failure[0], "t", None))
        return Segment(t, y, t_stop, y_stop, event, evaluations(), self.last_step, self.steps, step_ends,
                       step_times)


def _stopped_at_switch(watch, counted, switching, directions, rtol, atol, failure, evaluations, size):
    """The Segment of a segment stopped by a switch: locate the crossing in the step that crossed."""
    t_event, y_event, event = _locate(counted, switching, (watch.last_t, watch.last_y, watch.last_g), watch.hit,
                                      directions, rtol, atol, failure)
    if failure:
        raise failure[0]
    if watch.dense is not None:             # the requested times before the switch, inside the crossing step
        watch.dense.before_switch(watch.last_t, watch.last_y, watch.hit[0], watch.hit[1], t_event)
        if failure:
            raise failure[0]
    watch.ends.append(y_event)              # without dense outputs, the event also ends the outputs
    watch.end_times.append(t_event)
    return watch.segment(t_event, y_event, event, evaluations, size)


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
    t_code, y, code = dop853_code.dopri853(rhs, ta, ya, t, rtol=rtol, atol=atol, nsteps=DEFAULT_NSTEPS,
                                           first_step=t - ta, dfactor=REJECTION_FACTOR,
                                           beta=STEP_CONTROL_BETA)
    if code < 0:
        raise IntegrationError(
            f"ode.dop853 failed at t = {t_code:.6g} s while locating a switch: "
            f"{_reason(code, DEFAULT_NSTEPS)}. Try a solve_ivp method"
        )
    return np.array(y, dtype=float)
