"""One segment of a run with scipy.integrate.solve_ivp, with events at the switches.

Every accepted step goes to the run's watch (:mod:`~closedloop.simulation.watch`: change points,
the branch guard at det Phi_z = 0, dead positions of minimal coordinates, crawling) as it is
taken, so that a run stops where a check fails.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import ClosedLoopError, IntegrationError
from ..methods import scipy_integrate, solver_class, solver_classes
from . import switching as rule
from .options import stop_when_value

__all__ = ["segment", "counting_solver", "SOLVER_CLASSES", "STANDING_STEPS"]


def __getattr__(name):
    """``SOLVER_CLASSES``, solve_ivp's methods by name as OdeSolver classes (:func:`closedloop.methods.solver_classes`),
    and ``solve_ivp``: made on first use, so that importing this module does not import scipy.integrate."""
    if name == "SOLVER_CLASSES":
        return solver_classes()
    if name == "solve_ivp":
        return _solve_ivp()
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _solve_ivp():
    """scipy's solve_ivp, imported at the first call and kept as this module's ``solve_ivp`` (which a test
    may replace)."""
    function = globals().get("solve_ivp")
    if function is None:
        function = globals()["solve_ivp"] = scipy_integrate().solve_ivp
    return function


#: Successful steps in a row that do not advance t, after which a solver counts as stuck.
STANDING_STEPS = 1000


class _BudgetExceeded(Exception):
    """Raised inside the right-hand side when max_nfev is used up."""


def counting_solver(run, method):
    """The solve_ivp method as an OdeSolver subclass that records every accepted step on ``run``.

    Each accepted step goes to the run's watch (:meth:`~closedloop.simulation.watch.PathWatch.record`),
    which raises where a check fails; the integration stops (a failed step) when the run's
    ``max_steps`` is reached.
    """
    base = solver_class(method)
    max_steps = run.options.max_steps
    record = run.path.record

    class Counted(base):
        standing = 0                                # successful steps in a row that left t where it was

        def _step_impl(self):
            t_before = self.t
            success, message = super()._step_impl()
            if success and self.t == t_before:
                self.standing += 1                  # LSODA over a run of 1e-300 s: for ever, t = 0
                if self.standing >= STANDING_STEPS:
                    return False, f"{self.standing} steps in a row left t at {self.t:.6g} s"
            elif success:
                self.standing = 0
            if success and self.t != t_before:
                run.record_step(t_before, self.t)
                run.t_reached = self.t
                record(self.t, self.y.copy())
                if len(run.step_sizes) >= max_steps and self.t != self.t_bound:
                    run.steps_exhausted = True
                    return False, f"max_steps = {max_steps} reached"
            return success, message

    Counted.__name__ = Counted.__qualname__ = base.__name__
    return Counted


def _events(run, unpack, mode, t0):
    """Terminal events at every switch (and stop_when), for a segment that starts at ``t0`` on branch ``mode``.

    At ``t0`` an exact zero of a switching function counts as on the branch chosen
    (:func:`~closedloop.simulation.switching.on_chosen_side`), so that a crossing later in the
    first step is located there and not at the start.
    """
    switching_functions = run.force.switching_functions if run.names else None
    events = []
    for i in range(len(run.names)):
        def event(t, y, i=i):
            s, sd = unpack(y, t)
            value = switching_functions(t, s, sd)[i]
            return rule.on_chosen_side(value, mode[i]) if t == t0 else value

        event.terminal, event.direction = True, (-1.0 if mode[i] else 1.0)
        events.append(event)
    if run.options.stop_when is not None:
        stop_when = run.options.stop_when

        def stop(t, y):
            s, sd = unpack(y, t)
            return stop_when_value(stop_when, t, s, sd)

        stop.terminal, stop.direction = True, 1.0
        events.append(stop)
    return events, len(events)


def _guarded(rhs, run, reached, overflow):
    """The right-hand side with the evaluation budget and overflow caught."""
    budget = run.evaluations_left()
    count = [0]

    def guarded_rhs(t, y):
        reached[0] = t
        count[0] += 1
        if count[0] > budget:
            raise _BudgetExceeded
        try:
            return rhs(t, y)
        except (OverflowError, FloatingPointError) as error:
            # A trial stage may overflow where a shorter step would not: hand the
            # solver a non-finite slope, so that it rejects the step, and remember it.
            overflow.append((t, str(error)))
            return np.full(y.size, np.nan)
        except Exception:
            # The later stages of a step whose stage overflowed are evaluated at NaN: whatever
            # the formulation raises there (numpy's LinAlgError, a ConvergenceError) is that
            # overflow, and the step is rejected as above.  At a finite state it is the error.
            if np.isfinite(y).all():
                raise
            return np.full(y.size, np.nan)

    return guarded_rhs


def segment(run, t0, s0, sd0, mode):
    """Integrate on branch ``mode`` from ``t0`` until t_end or the next switch: a SegmentEnd."""
    y0, unpack, rhs = run.start_segment(s0, sd0, mode)
    events, terminal = _events(run, unpack, mode, t0)
    reached = [t0]                                  # last time the rhs was evaluated
    overflow = run.overflows = []                   # (t, message) of the overflows (the watch reads them too)
    run.path.start(t0, y0, s0, mode)
    try:
        sol = _solve(run, rhs, t0, y0, events, reached, overflow)
    except ClosedLoopError:
        run.path.failed(failed_at=reached[0])       # a change point passed before is the real cause
        raise
    run.nfev += sol.nfev
    event = t_stop = y_stop = None
    if sol.status == 1:                             # stopped by a switch or stop_when: the first one
        times = [te[0] if te.size else np.inf for te in sol.t_events[:terminal]]
        event = int(np.argmin(times))
        t_stop, y_stop = sol.t_events[event][0], sol.y_events[event][0]
    if sol.status == -1:
        run.path.failed()
        raise IntegrationError(_failure_message(run, sol.message, t0, overflow, reached[0]))
    run.path.end(t_stop, y_stop)
    t_out = np.asarray(sol.t, dtype=float)          # solve_ivp gives lists when t_eval is empty
    y_out = np.asarray(sol.y, dtype=float).reshape(y0.size, t_out.size)
    run.check_finite(t_out, y_out)
    run.store_segment(t_out, y_out, s0, mode, t0)
    return run.end_of_segment(t_stop, y_stop, unpack, event)


def _solve(run, rhs, t0, y0, events, reached, overflow):
    """solve_ivp over one segment; the budget and "could not locate a switch" become IntegrationErrors."""
    solve_ivp = _solve_ivp()
    options, formulation = run.options, run.formulation
    solver_options = dict(options.solver_options)
    if "first_step" in solver_options:              # a segment may be shorter than the first step asked for
        solver_options["first_step"] = min(solver_options["first_step"], run.t_end - t0)
    try:
        return solve_ivp(_guarded(rhs, run, reached, overflow), (t0, run.t_end), y0,
                        method=counting_solver(run, formulation.integrator(run.system, options.method)),
                        rtol=options.rtol, atol=options.atol, t_eval=run.outputs.due(t0), events=events or None,
                        **solver_options)
    except _BudgetExceeded:
        raise run.budget_error(reached[0]) from None
    except ValueError as error:
        if "must not contain infs or NaNs" in str(error):     # scipy's LU of Radau's or BDF's Newton matrix
            steps = f"last step {_last_step(run):.3g} s" if run.step_sizes else "before its first step"
            raise IntegrationError(
                f"{options.method_name} failed at t = {_time_reached(run, t0):.6g} s ({steps}) in a segment of "
                f"{run.t_end - t0:.3g} s: its Newton iteration met a matrix with non-finite entries (1/step beyond "
                f"the range of floating-point numbers, or a Jacobian that overflowed); {run.advice()}"
            ) from None
        if "is NaN; solver cannot continue" in str(error):   # brentq on the interpolant of a runaway step
            raise IntegrationError(
                f"{options.method_name} could not locate a switch or det Phi_z = 0 in the step after t = "
                f"{_time_reached(run, t0):.6g} s (step {_last_step(run):.3g} s): the step's interpolant is not "
                f"finite, the motion ran away; {run.advice()}"
            ) from None
        if "different signs" not in str(error):
            raise
        raise IntegrationError(
            f"{options.method_name} could not locate a switch ({', '.join(run.names)}) in the step after "
            f"t = {_time_reached(run, t0):.6g} s (step {_last_step(run):.3g} s): a switching function changed "
            "sign between the ends of the step but not along its interpolant, so the step is too long for the "
            "motion; try tighter tolerances or a max_step"
        ) from None


def _time_reached(run, t0):
    return t0 if run.t_reached is None or run.t_reached < t0 else run.t_reached


def _last_step(run):
    return run.step_sizes[-1] if run.step_sizes else math.nan


def _failure_message(run, message, t0, overflow, evaluated):
    """The IntegrationError text for a solve_ivp failure: time, quantity, what to try (``evaluated``: the time of
    the last right-hand side, where a force that is not finite is named)."""
    t, step, name = _time_reached(run, t0), _last_step(run), run.options.method_name
    force = run.path.force_clause_before(evaluated)
    if run.steps_exhausted:
        text = (f"{name} reached max_steps = {run.options.max_steps} at t = {t:.6g} s of "
                f"t_end = {run.t_end:g} s (last step size {step:.3g} s, mean "
                f"{np.mean(run.step_sizes[-100:]):.3g} s over the last 100 steps): the problem is stiff "
                "for this method, or the run too long")
        advice = run.advice() + ", or raise max_steps"
    elif message and "step size is less than spacing" in message:
        text = (f"{name} failed at t = {t:.6g} s: the step size underflowed (it must stay "
                f"above 10 ulp(t) = {10 * np.spacing(abs(t)):.3g} s; the last accepted step was "
                f"{step:.3g} s){force}")
        advice = (f"end the run before t = {t:.6g} s, or mend the force" if force else
                  f"no step that float64 resolves at this t meets the tolerances, so the motion or a force is "
                  f"most likely singular there: end the run before t = {t:.6g} s (an implicit method or looser "
                  "tolerances do not carry a run through a singularity)")
    else:
        text = f"{name} failed at t = {t:.6g} s (last step {step:.3g} s): {message}{force}"
        advice = run.advice()
    if overflow:
        text += (f"; the right-hand side overflowed ({overflow[-1][1]}) at t = {overflow[-1][0]:.6g} s, "
                 "the accelerations are beyond the range of floating-point numbers")
    return f"{text}; {advice}"
