"""One integration segment with the compiled DOP853 of scipy.integrate.ode.

``solve_ivp(method="DOP853")`` runs Dormand and Prince's 8(5,3) pair with its
step loop in Python, which costs about 4 µs per right-hand-side evaluation
before the right-hand side itself is called.  ``scipy.integrate.ode`` wraps
Hairer and Wanner's own DOP853 code [Hairer, Nørsett, Wanner, *Solving ODEs I*,
section II.10], the same pair with a compiled step loop: only the right-hand
side runs in Python.  That code has no events, and its own dense output is out
of reach (see below), so this module adds what :func:`closedloop.simulate` needs
from a segment:

- after every accepted step (the ``solout`` callback) the switching functions
  are evaluated at the step's end; a sign change in the watched direction stops
  the integration, as solve_ivp's terminal events do;
- the crossing is then located: a cubic Hermite interpolant over the step
  (from the states and right-hand sides at both ends) gives a first estimate,
  the step is redone from its start to that time with the same code, and
  Newton steps in time (each a Heun step of the state for the microsecond
  corrections left, else the step redone by the same code) put the
  switching function at zero.

Requested output times do not stop the code: it steps from ``t0`` to the end as
it would without them (the same steps, the same end state), and the outputs inside an
accepted step are evaluated with DOP853's own continuous extension of order 7
(Hairer's ``contd8``, [Hairer, Nørsett, Wanner, section II.6]), the dense output of
``solve_ivp(method="DOP853")``.  The code calls the right-hand side for every stage
and ``solout`` after every accepted step, so the stages of that step are the last
twelve calls (:class:`_DenseOutputs` records them and checks that they rebuild the
code's step end to round-off, else recomputes them); only the three extra stages
of the extension are new right-hand sides, and only in the steps that contain an
output time.  Hairer's code can compute the extension itself (``iout = 2``: the three extra
stages and the coefficients, in the work array that the caller passes and ``solout`` could
read), but scipy's C translation (``dop.c``, ``dp86co``, scipy 1.17) moves the pointer it
counts evaluations through in that branch (``nfcn += 3;`` where ``*nfcn += 3`` is meant), so
every later count writes past the caller's variable: here every call with ``iout = 2`` ended
the Python process with a segmentation fault, after 4, 20 and 25 accepted steps of three runs.
The code runs with scipy's settings of ``ode(...).set_integrator("dop853")`` but
two: the retry of a rejected step (:data:`REJECTION_FACTOR`) and the stabilised step size
control (:data:`STEP_CONTROL_BETA`).  The method is selected by
``simulate(..., method="ode.dop853")``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from .. import hermite
from ..errors import IntegrationError
from ..methods import COMPILED_METHOD
from . import dop853_code
from .switching import CHOSEN_SIDE

__all__ = ["METHOD", "ALLOWED_OPTIONS", "REJECTION_FACTOR", "STEP_CONTROL_BETA", "integrate_segment", "Segment", "step_stages",
           "continuous_extension", "continuous_extensions", "interpolate"]

#: The method name simulate() uses for this integrator.
METHOD = COMPILED_METHOD
#: The solver options this integrator takes (everything else is refused before integrating).
ALLOWED_OPTIONS = ("max_step", "first_step", "nsteps")
#: Steps allowed in one call of the compiled code before it gives up (per segment piece).
DEFAULT_NSTEPS = 200_000
#: The compiled code's ``fac1`` here (scipy's ``dfactor``, default 0.3): the ratio of the retry to a
#: rejected step.  Hairer's DOP853 retries a step of size h rejected with error estimate err > 1 at
#: ``h max(fac1, safe / err^(1/8))`` [Hairer, Nørsett, Wanner, section II.4]; scipy's C translation
#: (``dop.c``, ``dp86co``, scipy 1.17) computes ``h / min(facc1, facc1 / safe)``, that is ``fac1 h``
#: whatever err is, and the step after the retry may not grow (Hairer's rule after a rejection), so
#: with 0.3 each rejection cost 11 evaluations and two steps of 0.3 h.  The slider-crank's rejected
#: steps (the four cases, closed form, rtol 2e-9) had err from 1 to 36, for which Hairer's rule
#: retries at 0.57 h to 0.9 h; with 0.6 a retry passes for err < 0.6^-8 = 60.  ``fac1`` bounds
#: nothing else: an accepted step (err <= 1) shrinks to no less than ``safe`` = 0.9 of the last with
#: beta = 0, and to about 0.62 of it with :data:`STEP_CONTROL_BETA` (0.9 x 1e-4^0.04).  In a
#: scipy whose code follows Hairer's rule, 0.6 is only its floor.
REJECTION_FACTOR = 0.6
#: The compiled code's ``beta`` here (scipy's default 0): after an accepted step with error
#: estimate err (the one before: err_old), the next is ``h min(fac2, max(fac1, safe
#: err_old^beta / err^(1/8 - beta/5)))`` (fac1 = :data:`REJECTION_FACTOR`, fac2 = 6)
#: [Hairer, Nørsett, Wanner, section II.4; Hairer and Wanner, section IV.2, "stabilized step
#: size control"], which damps the cycle of a step that grows, is rejected and grows again.  0.04 is Hairer's value for DOPRI5 (his DOP853 leaves it
#: at 0).  Measured on the slider-crank (ClosedForm(1, 1), the four cases over 20 s, rtol = atol
#: from 1e-7 to 1e-11 at 1, 2 and 5 per decade, errors at 10 and 20 s against DOP853 at 1e-13):
#: 5.5 % fewer right-hand sides than 0 (geometric mean; 2.5 % to 8 % per case), and errors
#: smaller too (mean log10(error / rtol) 0.63 with 0, 0.49 with 0.04; largest 2.20 and 1.56).
#: 0.02 to 0.06 save about as much; 0.08 costs more than 0.
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
    calls = None if outputs is None else _Calls()  # the calls, for the stages of the steps
    counted, evaluations, record = _counting(rhs, max_nfev, failure, calls)
    directions = tuple(float(d) for d in directions)
    dense = None if outputs is None else _DenseOutputs(counted, calls, outputs, t0, y0, t_end, record,
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


class _Calls:
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
    in ``failure`` and returns NaN, and the segment re-raises it.  With a :class:`_Calls`
    ``calls``, every call made while recording is on (at first it is) appends its time
    and its values to it (for :class:`_DenseOutputs`); without one, ``record`` does nothing.
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


class _DenseOutputs:
    """The requested output times of a segment, from DOP853's continuous extension of the accepted steps.

    The compiled code's right-hand side records every call's time and values in ``calls``
    (see :func:`_counting`); the calls since the last accepted step are kept.  When ``solout`` reports an
    accepted step from ``ta`` to ``tb``, its last twelve calls are the eleven
    stages at ``ta + c_i h`` (i = 2..12) and f at the new step end (the code's
    FSAL evaluation); the step's first stage is f at ``ta``, the previous step's
    last call.  Calls of rejected steps come before them and are skipped.  An output
    time at a step end is the code's state there.  A step that holds output times
    inside it is kept (its ends and its recorded stages: a few references, no
    arithmetic), and when the segment ends :meth:`outputs` evaluates all of them
    at once (:func:`_evaluate_held_steps`): the stages are checked (their times, and
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
    calls : _Calls
        Where ``rhs`` records its calls.
    times : array_like
        The requested output times; those outside ``[t0, t_end]`` are ignored.
    t0, y0 : float, ndarray
        The segment's start (an output if ``t0`` is requested).
    t_end : float
    record : callable, optional
        ``record(on)`` turns the recording of the calls into ``calls`` on or off (see :func:`_counting`).
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
        self.held = []                      # _HeldStep of the steps that hold output times inside them
        # their 13 recorded stages (f at ta, then the last twelve calls), one step after another, n floats a
        # stage; zeros for a step whose calls were not all recorded (its stages are recomputed)
        self.stages = []
        self.missing = [0.0] * ((_STAGES + 1) * self.size)
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
        times, values = calls.last(_STAGES, n)
        self.f_start = values[-n:] if values is not None and times and times[-1] == tb else None
        if tb >= self.next_time:
            self._hold(ta, ya, tb, yb, f_start, times, values, int(self.times.searchsorted(tb, "right")))
        calls.clear()
        self.record(self.next_time - tb <= _LOOKAHEAD * (tb - ta))

    def crossed(self):
        """``solout`` stopped the code at a step that crossed a switch: keep that step's calls."""
        self.crossing = (*self.calls.last(_STAGES, self.size), self.f_start)

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
            _evaluate_held_steps(self.rhs, held, stages, self.times, states)
        return self.times[:count].copy(), states

    def _hold(self, ta, ya, tb, yb, f_start, times, values, stop):
        """The output times ``next .. stop-1`` lie in the step ``(ta, ya)`` to ``(tb, yb)``: keep it, with its
        last recorded calls (``times``, and their ``values``, or None if some call did not give n values)."""
        start, inside = self.next, stop if self.times[stop - 1] != tb else stop - 1
        if inside > start:
            complete = f_start is not None and values is not None and len(times) == _STAGES
            if complete:
                self.stages.extend(f_start)
                self.stages.extend(values)
            else:
                self.stages.extend(self.missing)
            self.held.append(_HeldStep(ta, ya, tb, yb, complete, times[0] if times else math.nan,
                                       times[-1] if times else math.nan, start, inside))
        self.next = inside
        if stop > inside:                   # an output at the step end: the code's own state
            self._known(1, yb)

    def _known(self, count, y):
        self.known.append((self.next, self.next + count, np.asarray(y, dtype=float)))
        self.next += count
        self.next_time = float(self.times[self.next]) if self.next < self.times.size else math.inf


class _HeldStep(NamedTuple):
    """An accepted step that holds output times: its ends, its recorded calls, which outputs it holds."""

    ta: float
    ya: np.ndarray
    tb: float
    yb: np.ndarray
    complete: bool           # f at ta and its last twelve calls were recorded (in _DenseOutputs.stages)
    first_call: float        # the time of the first of its last twelve recorded calls (the stage 2), or nan
    last_call: float         # the time of its last recorded call (f at tb), or nan
    start: int               # the outputs start .. stop-1 lie inside it
    stop: int


def _evaluate_held_steps(rhs, held, stages, times, states):
    """Write into ``states`` the outputs inside the ``held`` steps (:class:`_HeldStep`), all at once.

    ``stages`` holds their 13 recorded stages, one step after another (:attr:`_DenseOutputs.stages`).

    Their stages come from the recorded calls where those pass the check of
    :func:`_rebuilds_step_ends`, else are recomputed (:func:`step_stages`) and checked
    again; then :func:`continuous_extensions` and one product per step with the basis of
    :func:`_basis` at all outputs.
    """
    count, size = len(held), states.shape[0]
    ta, tb, h, ya, yb = _held_ends(held)
    K = np.empty((_STAGES + 4, count, size))               # stage, step, component
    complete = np.array([step.complete for step in held])
    K[:_STAGES + 1] = np.fromiter(stages, float, len(stages)).reshape(count, _STAGES + 1, size).transpose(1, 0, 2)
    first_call = np.array([step.first_call for step in held])
    last_call = np.array([step.last_call for step in held])
    checked = (complete
               & (np.abs(first_call - (ta + _C[1] * h)) <= 1e-9 * np.abs(h) + 1e-15 * np.maximum(np.abs(ta), np.abs(tb)))
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


#: DOP853's coefficients (Hairer's, as scipy's DOP853 carries them): the 12 stages of the step,
#: its weights, and the three extra stages and the D matrix of the continuous extension.
#: (scipy.integrate.DOP853's class attributes, from the module they are taken from:
#: :func:`closedloop.simulation.dop853_code.coefficients`.)
_COEFFICIENTS = dop853_code.coefficients()
_STAGES = _COEFFICIENTS.N_STAGES                                  # 12
_A, _B, _C = _COEFFICIENTS.A[:_STAGES, :_STAGES], _COEFFICIENTS.B, _COEFFICIENTS.C[:_STAGES]
_A_EXTRA, _C_EXTRA, _D = _COEFFICIENTS.A[_STAGES + 1:], _COEFFICIENTS.C[_STAGES + 1:], _COEFFICIENTS.D
_ABS_B = np.abs(_B)
#: (row, a_row[:row], c) of the extension's three extra stages.
_EXTRA_STAGES = [(s, a[:s].copy(), c) for s, (a, c) in enumerate(zip(_A_EXTRA, _C_EXTRA), start=_STAGES + 1)]
_EPS = np.finfo(float).eps
#: How far ahead of a step end, in units of that step's size h, the next output time makes
#: _DenseOutputs record the calls of the next step.  The compiled code lets a step grow at most
#: IFACTOR = 6 times (:mod:`~closedloop.simulation.dop853_code`) and stretches the last step to t_end by
#: at most 1 %, so the two steps that follow end before 6.06 h + 6.06^2 h = 42.8 h (here with a 20 %
#: margin); a step that grew more than that would only have its stages recomputed (13 more right-hand
#: sides), never a wrong output.
_LOOKAHEAD = 1.2 * (1.01 * dop853_code.IFACTOR) * (1.0 + 1.01 * dop853_code.IFACTOR)
#: Outputs whose basis (:func:`_basis`, 8 rows) is computed at once: 8 x 2000 floats, 125 kB, under
#: glibc's threshold (128 kB) for allocating with mmap, whose pages are faulted in anew every time
#: (measured here: 1.35 µs per 4 kB page; a basis of 10 000 outputs at once cost 0.2 ms in faults).
_GROUP_OUTPUTS = 2000
#: A step end rebuilt from the stages may differ from the code's by this many units of round-off
#: of the sum ``ya + h sum b_i k_i`` (the code sums in another order, and its h differs from
#: ``tb - ta`` by round-off in tb).
_ROUND_OFF_UNITS = 64.0


def _extension_form():
    """Hairer's ``contd8`` coefficients as ``F = h F_of_K K + (the terms in yb - ya)``: ``F_of_K`` (7, 16).

    ``F0 = yb - ya``, ``F1 = h k_1 - F0``, ``F2 = 2 F0 - h (k_1 + k_13)``, ``F3..F6 = h D K``.
    """
    F_of_K = np.zeros((7, _STAGES + 4))
    F_of_K[1, 0] = 1.0
    F_of_K[2, [0, _STAGES]] = -1.0
    F_of_K[3:] = _D
    return F_of_K


_F_OF_K = _extension_form()


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
    K = np.empty((_STAGES + 4, ya.size))
    K[0] = f_start
    for s in range(1, _STAGES):
        K[s] = rhs(ta + _C[s] * h, ya + h * (_A[s, :s] @ K[:s]))
    if y_end is None:
        t_end, y_end = ta + h, ya + h * (_B @ K[:_STAGES])
    K[_STAGES] = rhs(t_end, y_end)
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
    h = tb - ta
    h_column = h[:, None]
    K = stages
    for s, a, c in _EXTRA_STAGES:                       # K[:s] as stage x (step, component): one product
        arguments = ya + h_column * (a @ K[:s].reshape(s, -1)).reshape(ya.shape)
        row = K[s]
        for k, t in enumerate((ta + c * h).tolist()):
            row[k] = rhs(t, arguments[k])           # one at a time: a right-hand side may reuse its array
    F = (_F_OF_K @ K.reshape(K.shape[0], -1)).reshape(7, *ya.shape) * h_column
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
    K = stages[:_STAGES].reshape(_STAGES, -1)
    # |h sum b_i k_i - (yb - ya)| against the round-off of the sum and of h (up to |tb| eps |sum b_i k_i|)
    scale = np.abs(ya) + (np.abs(h) + np.abs(tb))[:, None] * (_ABS_B @ np.abs(K)).reshape(ya.shape)
    return (np.abs(ya + h[:, None] * (_B @ K).reshape(ya.shape) - yb) <= _ROUND_OFF_UNITS * _EPS * scale).all(axis=1)


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
