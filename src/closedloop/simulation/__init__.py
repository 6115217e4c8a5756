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
    formulation : Formulation, optional
        Any formulation (:data:`closedloop.formulations.REGISTRY` holds the
        library's); default ``Baumgarte(5, 5)``, Baumgarte's own choice.
    method : str or OdeSolver, optional
        One of :data:`SOLVER_METHODS` or an OdeSolver subclass; default "RK45".
        A formulation may refuse some (:func:`~closedloop.simulation.options.methods_taking`
        gives those it takes).
    rtol, atol : float or array_like, optional
        Tolerances of the integrator, > 0 (an array: one per state entry).
    t_eval : array_like, optional
        Increasing output times; default: the integrator's own steps.
    multipliers : bool, optional
        Also compute lambda of (5) at the output times.
    stop_when : callable, optional
        ``stop_when(t, s, sd) -> float``: the run ends where this crosses zero
        upward (the result's ``stopped_at``); not evaluated while the
        mechanism is stuck.  Not with ``switching="naive"``.
    sticking_resolution : float, optional
        Sampling interval [s] for the release of a stuck state.
    max_segments : int, optional
        Bound on the number of segments between switches.
    switching : {"events", "naive"}, optional
        "events" (default): stop at every switch and apply the rules of
        :mod:`closedloop.simulation.switching`.  "naive": choose the force's
        branch from the state at every evaluation (the contrast that chatters).
    max_nfev : int, optional
        Bound on the right-hand-side evaluations of the whole run; default none.
    max_steps : int, optional
        Bound on the accepted steps of the whole run (default :data:`MAX_STEPS`).
    work : bool, optional
        Also integrate the work W of the non-conservative forces (the result's
        ``work``), for the energy balance ``Delta(T + Pi) = W``.  Not with
        ``switching="naive"``.
    branch_limit : float, optional
        The branch guard's bound on the Kantorovich number where det Phi_z
        changes sign (default :data:`BRANCH_LIMIT`; ``math.inf`` turns the
        guard off); see :mod:`closedloop.simulation.watch`.
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
        If the integrator fails, the run needs more than ``max_steps`` steps
        or ``max_nfev`` evaluations, the right-hand side overflows, the state
        stops being finite or chatters on a switch: the message names the
        time, what went bad and what to try.  With ``switching="naive"`` the
        error's attribute ``result`` holds the run up to that time.
    SingularConfigurationError
        If the formulation meets a configuration it can not pass: the message
        names the time and the matrix that became singular.

    Notes
    -----
    Output times never change the integration: the steps and the end state are
    those of the run without them, and each output comes from the method's own
    interpolant over the step that holds it (for DOP853 and "ode.dop853", the
    7th-order continuous extension, 3 more right-hand sides per step that holds
    an output).  ``benchmarks/output_grid_cost.py`` measures what outputs cost
    and how accurate they are, per method.
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
