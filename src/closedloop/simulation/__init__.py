"""simulate(): integrate a closed-loop system, from switch to switch of its forces.

The run is split into segments.  In each segment the branch (``mode``) of every
switched force is frozen, so the right-hand side is smooth, and the integration
stops where a switching function crosses zero; there the next branch is chosen
by the switching rule of :mod:`closedloop.simulation.switching` (which also
holds the sticking rule).  The pieces:

- :mod:`~closedloop.simulation.options`: the arguments, validated once, frozen;
- :mod:`~closedloop.simulation.run`: the segment loop, sticking, and what the runners share;
- :mod:`~closedloop.simulation.solve_ivp_runner`: a segment with solve_ivp, events and the branch guard;
- :mod:`~closedloop.simulation.dop853_runner` (with :mod:`~closedloop.simulation.dop853`):
  a segment with the compiled DOP853 of scipy.integrate.ode;
- :mod:`~closedloop.simulation.naive`: naive switching, the contrast that chatters;
- :mod:`~closedloop.simulation.result`: :class:`SimulationResult` and the output assembly.
"""

from __future__ import annotations


import numpy as np

from ..errors import ClosedLoopError, IntegrationError
from ..formulations import Baumgarte
from ..loading import run_clock
from . import dop853_runner, solve_ivp_runner
from .naive import integrate_naive
from .options import BRANCH_LIMIT, INITIAL_TOLERANCE, MAX_STEPS, SOLVER_METHODS, SWITCHING, run_options
from .result import SimulationResult, SwitchEvent, multipliers
from .run import Run

__all__ = ["simulate", "SimulationResult", "SwitchEvent", "SOLVER_METHODS", "SWITCHING", "BRANCH_LIMIT",
           "MAX_STEPS", "INITIAL_TOLERANCE"]


def simulate(system, initial_state, t_end=20.0, *, t_start=0.0, formulation=None, method="RK45",
             rtol=1e-9, atol=1e-9, t_eval=None, multipliers=False, stop_when=None,
             sticking_resolution=0.01, max_segments=100_000, switching="events", max_nfev=None,
             max_steps=MAX_STEPS, work=False, branch_limit=BRANCH_LIMIT, **options):
    """Integrate Lagrange's equations with multipliers from a consistent initial state.

    Parameters
    ----------
    system : System
        The model with its parameter values and forces.
    initial_state : InitialState
        Consistent ``(s0, s0')``, e.g. from :func:`consistent_initial_state`.
    t_end : float, optional
        Final time, > ``t_start``.  Default 20 s.
    t_start : float, optional
    formulation : Augmented, Baumgarte, Orthogonal, Minimal, NullSpace, ClosedForm or Projected, optional
        Default ``Baumgarte(5, 5)``, Baumgarte's own choice.
    method : str or OdeSolver, optional
        Any solve_ivp method; default "RK45".  Projected takes only RK23, RK45
        and DOP853 (see :mod:`closedloop.formulations.projected`).
    rtol, atol : float, optional
        Tolerances passed to solve_ivp, > 0.
    t_eval : array_like, optional
        Output times; default: the solver's own steps.  What they cost and
        how accurate they are, per method: see the Notes.
    multipliers : bool, optional
        Also compute lambda of (5) at the output times.
    stop_when : callable, optional
        ``stop_when(t, s, sd) -> float``: the run ends early, at the time this
        crosses zero upward (e.g. a speed limit for a run-away motion).  The
        result's ``stopped_at`` is then that time.  It is not evaluated
        while the mechanism is stuck (its state is then constant).  Not with
        ``switching="naive"``.
    sticking_resolution : float, optional
        Sampling interval (s) for the release of a stuck state.
    max_segments : int, optional
        Bound on the number of segments between switches.
    switching : {"events", "naive"}, optional
        "events" (default): stop at every switch and apply the sticking rule.
        "naive": choose the force's branch from the state at every evaluation,
        with no events (a contrast that chatters; see :mod:`closedloop.simulation.naive`).
    max_nfev : int, optional
        Bound on the right-hand-side evaluations of the whole run; default none.
        A naive run checks it between steps, so it may pass it by one step's
        evaluations.
    max_steps : int, optional
        Bound on the accepted integration steps of the whole run (default
        :data:`MAX_STEPS`).  A run that needs more raises IntegrationError
        naming the time reached and the step size: typically an explicit
        method on a stiff problem.
    work : bool, optional
        Also integrate the work of the non-conservative forces (the result's
        ``work``), for the energy balance ``Delta(T + Pi) = W``.  Not with
        ``switching="naive"``.
    branch_limit : float, optional
        The branch guard's bound on the Kantorovich number where det Phi_z
        changes sign (default :data:`BRANCH_LIMIT`; ``math.inf`` turns the guard
        off, to show what it prevents); see :mod:`closedloop.simulation.solve_ivp_runner`.
    **options
        Further solve_ivp options (``max_step``, ``first_step``, ...).

    Returns
    -------
    SimulationResult

    Raises
    ------
    InputError
        Before any integration, for a parameter outside its range.
    IntegrationError
        If the integrator fails (the step size underflows), the run needs more
        than ``max_steps`` steps or ``max_nfev`` evaluations, the right-hand
        side overflows, the state stops being finite, or the state chatters on
        a switch: the message names the time, the quantity that went bad, and
        what to try instead.  With ``switching="naive"`` the error's
        attribute ``result`` holds the run up to that time.
    SingularConfigurationError
        If the formulation meets a configuration it can not pass (see the
        formulations and the branch guard of
        :mod:`closedloop.simulation.solve_ivp_runner`): the message names the time
        and the condition number that went bad.

    Notes
    -----
    **Output times** (``t_eval``) never change the integration: every method
    takes the same steps and reaches the same end state (to round-off) with and
    without them, and each output between two step ends comes from the method's own
    interpolant over the step that holds it (in a segment stopped by a switch,
    from the step that crossed it, for the times before the switch).  An
    output is therefore about as accurate as the tolerance asks, not always as
    accurate as the step ends, which are often better.  Per method:

    - ``"RK45"``: the pair's 4th-order interpolant; no extra right-hand sides.
    - ``"RK23"``: a 3rd-order Hermite interpolant; no extra right-hand sides.
    - ``"DOP853"``: the 7th-order continuous extension of Dormand and Prince
      (Hairer's ``contd8``): 3 extra right-hand sides in every step that holds
      an output time (a step costs 12), however many outputs it holds.
    - ``"Radau"``: the collocation polynomial of the step (order 3 inside the
      step, order 5 at its ends); no extra right-hand sides.
    - ``"BDF"``, ``"LSODA"``: the interpolating polynomials of their
      multistep formulas; no extra right-hand sides.
    - ``"ode.dop853"``: the code steps from switch to switch as without outputs,
      and the outputs inside a step come from the same 7th-order continuous
      extension as DOP853's, with the step's stages recorded as the compiled code
      computes them: 3 extra right-hand sides per step that holds an output time
      (see :mod:`closedloop.simulation.dop853`).

    Measured on case 2 of the paper over 1 s (ClosedForm, rtol = atol = 1e-9;
    ``benchmarks/output_grid_cost.py``): 10 000 evenly spaced outputs left
    the steps and the end state of every method unchanged; nfev unchanged for
    RK45, RK23, Radau, BDF and LSODA and 1.25 times that without a grid for
    DOP853 and ode.dop853 (the same with 50 000 outputs).  Against a tight
    reference integrated from each step's start, the largest error of the
    outputs was, in units of ``atol + rtol |y|``: RK45 0.68 (0.68 at its step
    ends), RK23 156 (155), DOP853 0.093 (0.004), Radau 0.57 (0.013), BDF 6.8
    (6.8), LSODA 1.3 (1.3), ode.dop853 0.051 (0.002): the outputs are within
    the error the steps already carry, and the low-order and multistep
    methods' global errors are far above their tolerance anyway.  Process time is
    another matter: each output costs some (interpolation, unpacking; the
    residuals |f| and |f'| at the outputs only when first read, see
    :class:`SimulationResult`), and with DOP853 and ode.dop853 so does each step
    that holds one.  With 10 000 outputs a run took, against the same run
    without them (each timed after a run of its own kind): ode.dop853 1.86
    times as long (1.62 over 20 s, where nearly every step holds outputs),
    DOP853 1.91 (1.43 over 20 s), RK45 1.42, RK23 1.46, Radau 1.11, BDF 1.21
    and LSODA 4.00 (1.52 over 20 s).  Of ode.dop853's extra 0.85 ms over 1 s,
    the three right-hand sides per step are 0.09 ms and the interpolant's
    arithmetic 0.13 ms; the rest is Python work per step, per segment and per
    output, on a run that is itself short (1 ms).

    The fixed-step :func:`closedloop.fixed_step.rk4` is not one of these
    methods and takes no output times: its outputs are its steps.
    """
    formulation = Baumgarte() if formulation is None else formulation
    run_settings = run_options(
        system, initial_state, formulation, t_start=t_start, t_end=t_end, method=method, rtol=rtol, atol=atol,
        t_eval=t_eval, multipliers=multipliers, stop_when=stop_when, sticking_resolution=sticking_resolution,
        max_segments=max_segments, switching=switching, max_nfev=max_nfev, max_steps=max_steps, work=work,
        branch_limit=branch_limit, solver_options=options)
    start = run_clock()                        # process time, the modules loaded on first use left out
    run = Run(system, formulation, run_settings)
    # A motion that runs away (loose tolerances, a fast start) reaches numbers beyond float's range:
    # numpy's inf and NaN then end the run with the errors below, not with RuntimeWarnings on the way,
    # and Python's OverflowError (the generated code, at a switch) is an IntegrationError too.
    message = None
    try:
        with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
            if switching == "naive":
                message = integrate_naive(run, t_start, initial_state.s, initial_state.sd)
            else:
                runner = dop853_runner if run_settings.compiled else solve_ivp_runner
                run.integrate(runner.segment, t_start, initial_state.s, initial_state.sd)
    except (OverflowError, FloatingPointError) as error:
        raise run.overflow_error(error) from None
    except ClosedLoopError:
        run.path.flush()                        # a change point passed before is the real cause
        raise
    if switching == "naive":
        if message is not None:
            error = IntegrationError(message)
            error.result = _result(run, start, with_multipliers=False)
            raise error
    else:
        run.path.flush()
    return _result(run, start, with_multipliers=run_settings.multipliers)


def _result(run, start, with_multipliers):
    """The SimulationResult of a finished (or, for a naive run, capped) run."""
    system, formulation, options = run.system, run.formulation, run.options
    t, s, sd, modes, work_done = run.outputs.assemble(options.work)
    cpu_time = run_clock() - start
    lam = multipliers(system, formulation, t, s, sd, modes()) if with_multipliers else None
    step_f, step_fd = run.path.largest_residuals
    return SimulationResult(
        t=t, s=s, sd=sd, constraint_error=None, velocity_constraint_error=None, residuals=system.constraint_errors,
        multipliers=lam, nfev=run.nfev, cpu_time=cpu_time, switch_events=run.switch_events,
        sticking_intervals=run.sticking_intervals, stopped_at=run.stopped_at,
        partition_singularities=run.partition_singularities, switching=options.switching,
        formulation=formulation.name, method=options.method_name, rtol=options.rtol, atol=options.atol,
        coordinate_names=tuple(system.coordinate_names),
        step_sizes=np.asarray(run.step_sizes, dtype=float), step_starts=np.asarray(run.step_starts, dtype=float),
        work=work_done,
        step_constraint_error=step_f, step_velocity_constraint_error=step_fd,
    )
