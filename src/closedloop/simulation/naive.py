"""A run with naive switching: the contrast that shows why simulate() stops at every switch.

No events and no sticking rule: the force's branch is chosen from the current state at every
evaluation (a plain if-statement).  Such a run chatters on x_C' = 0; ``max_nfev`` bounds it, and
the solver is stepped by hand so that a run cut short keeps what it computed.
"""

from __future__ import annotations

import numpy as np

from ..errors import ClosedLoopError
from ..methods import solver_class
from .result import Piece

__all__ = ["integrate_naive"]


def _rhs_choosing_branch(run, unpack, changes):
    """The right-hand side that picks the force's branch from the state at each call."""
    system, formulation, force = run.system, run.formulation, run.force
    rhs_on, last_mode = {}, [None]

    def rhs(t, y):
        run.nfev += 1
        mode = ()
        if force is not None:
            mode = force.mode_at(t, *unpack(y, t))
            if last_mode[0] is not None:
                changes[:] += np.array(mode) != np.array(last_mode[0])
            last_mode[0] = mode
        if mode not in rhs_on:
            rhs_on[mode] = formulation.make_rhs(system, mode, unpack)
        return rhs_on[mode](t, y)

    return rhs


def _capped_message(run, solver, changes):
    busiest = int(np.argmax(changes)) if changes.size else None
    where = (f"; the force switched {changes[busiest]} times on {run.names[busiest]!r} (chattering)"
             if busiest is not None and changes[busiest] else "")
    return (f"naive switching used up max_nfev = {run.options.max_nfev} right-hand-side evaluations "
            f"at t = {solver.t:.6g} s of {run.t_end:g} s, last step {solver.step_size:.3g} s{where}; "
            "use switching='events'")


def integrate_naive(run, t0, s0, sd0):
    """One integration of ``run`` with naive switching; None when t_end is reached, else an error message.

    Every accepted step goes to the run's watch (:mod:`~closedloop.simulation.watch`), as on the other runners.
    """
    system, formulation, options = run.system, run.formulation, run.options
    unpack = formulation.unpacker(system)
    unpack.seed(s0)
    changes = np.zeros(len(run.names), dtype=int)
    y0 = formulation.pack(system, s0, sd0)
    run.path.start(t0, y0, s0, None)           # the force's branch is chosen at every evaluation: no one mode
    # the formulation's integrator: Projected's with its projection
    solver = solver_class(formulation.integrator(system, options.method))(
        _rhs_choosing_branch(run, unpack, changes), t0, y0, run.t_end, rtol=options.rtol, atol=options.atol,
        **options.solver_options)
    t_eval = options.t_eval
    if t_eval is None:
        times, states = [t0], [solver.y.copy()]
    else:
        first = t_eval[t_eval <= t0]
        times, states = list(first), [solver.y.copy()] * first.size
    try:
        message = _steps(run, solver, changes, times, states)
    except ClosedLoopError:
        run.path.failed(solver.t)                # a change point passed before is the real cause
        raise
    if message is None:
        run.path.end()
    else:
        run.path.failed()
    t = np.array(times)
    y = np.array(states).reshape(t.size, -1).T
    outputs = formulation.unpacker(system)
    outputs.seed(s0)
    pairs = [outputs(y[:, k], t[k]) for k in range(t.size)]
    run.outputs.pieces.append(Piece(t, np.array([p[0] for p in pairs]).T, np.array([p[1] for p in pairs]).T,
                                    None, None, None))
    return message


def _steps(run, solver, changes, times, states):
    """Step ``solver`` to t_end, keeping the outputs in ``times``, ``states``; None, or why it stopped early."""
    options, t_eval = run.options, run.options.t_eval
    while solver.status == "running":
        if options.max_nfev is not None and run.nfev >= options.max_nfev:
            return _capped_message(run, solver, changes)
        solver.step()
        if solver.status == "failed":
            return (f"{options.method_name} failed at t = {solver.t:.6g} s with naive switching "
                    f"(step size {solver.step_size:.3g} s); use switching='events'")
        run.record_step(solver.t_old, solver.t)
        run.path.record(solver.t, solver.y.copy())
        if t_eval is None:
            times.append(solver.t)
            states.append(solver.y.copy())
        else:                                  # the step's own interpolant, as solve_ivp does
            inside = t_eval[(t_eval > solver.t_old) & (t_eval <= solver.t)]
            if inside.size:
                times.extend(inside)
                states.extend(np.atleast_2d(solver.dense_output()(inside).T))
        if len(run.step_sizes) >= options.max_steps and solver.status == "running":
            return (f"naive switching reached max_steps = {options.max_steps} at t = {solver.t:.6g} s of "
                    f"{run.t_end:g} s (step size {solver.step_size:.3g} s); use switching='events'")
    return None
