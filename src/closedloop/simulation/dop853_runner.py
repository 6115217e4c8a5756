"""One segment of a run with the compiled DOP853 of scipy.integrate.ode (method ``"ode.dop853"``).

The compiled code has no events and no dense output; :func:`closedloop.simulation.dop853.integrate_segment`
adds the switch location, and this runner adds what :func:`closedloop.simulate` needs around it:
budgets, outputs and the end state (shared with the solve_ivp runner through
:class:`~closedloop.simulation.run.Run`), and every accepted step handed to the run's watch
(:mod:`~closedloop.simulation.watch`: change points, the branch guard, dead positions).
"""

from __future__ import annotations

from ..errors import ClosedLoopError, IntegrationError
from . import dop853
from .options import stop_when_value

__all__ = ["segment"]


def _switching_values(run, unpack):
    """``switching(t, y) -> list``: the values of the switching functions (and stop_when) at a state."""
    switching_values = run.force.switching_values if run.names else None
    stop_when = run.options.stop_when
    if stop_when is None and switching_values is not None:        # the common case, called after every step
        def switching(t, y):
            s, sd = unpack(y, t)
            return switching_values(t, s, sd)

        return switching

    def switching(t, y):
        if switching_values is None and stop_when is None:
            return ()
        s, sd = unpack(y, t)
        values = switching_values(t, s, sd) if switching_values is not None else []
        return values + [stop_when_value(stop_when, t, s, sd)] if stop_when is not None else values

    return switching


def segment(run, t0, s0, sd0, mode):
    """Integrate on branch ``mode`` from ``t0`` until t_end or the next switch: a SegmentEnd."""
    options = run.options
    y0, unpack, rhs = run.start_segment(s0, sd0, mode)
    run.path.start(t0, y0, s0, mode)
    directions = [-1.0 if on else 1.0 for on in mode[:len(run.names)]]
    if options.stop_when is not None:
        directions.append(1.0)
    solver_options = dict(options.solver_options)
    first_step = solver_options.pop("first_step", None)     # the user's first step: first segment only
    first_step = first_step if first_step is not None and not run.outputs.pieces else None
    try:
        result = dop853.integrate_segment(      # the user's nsteps, if given, is among solver_options
            rhs, t0, y0, run.t_end, rtol=options.rtol, atol=options.atol,
            switching=_switching_values(run, unpack), directions=directions, outputs=run.outputs.due(t0),
            outputs_increasing=True,
            max_nfev=run.evaluations_left(), max_steps=options.max_steps - len(run.step_sizes),
            first_step=first_step if first_step is not None else run.last_step_size, on_step=run.path.record,
            **solver_options)
    except dop853.BudgetExceeded as exceeded:
        run.path.failed()
        raise run.budget_error(exceeded.t) from None
    except ClosedLoopError as error:                # a change point passed earlier is the real cause
        run.path.failed(getattr(error, "failed_at", None))
        if run.path.error is None and not getattr(error, "max_steps_reached", False):
            times = [getattr(error, name, None) for name in ("t", "failed_at", "last_call")]
            times = [t for t in times if t is not None and t == t]
            force = run.path.force_clause_before(max(times)) if times else ""
            if force:                                # a force that is not finite is the cause: named
                raise IntegrationError(f"ode.dop853 failed at t = {max(times):.6g} s{force}; end the run before "
                                       f"t = {max(times):.6g} s, or mend the force") from None
        if getattr(error, "max_steps_reached", False):  # simulate's max_steps, not the compiled code's nsteps
            raise IntegrationError(                 # (the watch counted this segment's steps only)
                f"ode.dop853 reached max_steps = {options.max_steps} at t = {error.t:.6g} s of t_end = "
                f"{run.t_end:g} s: the problem is stiff for this method, or the run too long; {run.advice()}, "
                "or raise max_steps") from None
        raise
    run.nfev += result.nfev
    run.path.end(result.t_stop if result.event is not None else None, result.y_stop)
    run.last_step_size = result.last_step
    run.step_starts.extend(result.step_times[:len(result.steps)].tolist())
    run.step_sizes.extend(result.steps)
    run.t_reached = result.t_stop
    run.check_finite(result.t, result.y)
    run.store_segment(result.t, result.y, s0, mode, t0)
    return run.end_of_segment(result.t_stop, result.y_stop, unpack, result.event)
