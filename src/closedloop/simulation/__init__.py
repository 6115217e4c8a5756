"""simulate(): integrate a closed-loop system with scipy.integrate.solve_ivp.

The run is split into segments.  In each segment the branch (``mode``) of every
switched force is frozen, so the right-hand side is smooth, and an event stops
the integration where a switching function crosses zero.  At the switch the
new branch is chosen from the rate of the switching function on either side:

- both sides move the state the same way: the state crosses (or turns back);
- both sides push the state onto the surface (Filippov sliding): for a
  velocity-level switch that may stick, the **sticking rule** applies.

Sticking rule
-------------
The slider-crank's gas force acts only while ``x_C' > 0``.  When the slider comes
to rest while the drive pushes it outward, but the gas force, once the slider
moved, would push it back harder, neither branch is consistent: the slider sticks.
For a one-degree-of-freedom mechanism ``x_C' = 0`` means the whole mechanism is at
rest, so the rule is: hold ``s`` fixed and ``s' = 0`` while the force needed to
hold it lies between the two branches, that is while the rate of the switching
function is > 0 on the "off" branch and < 0 on the "on" branch.  Release happens
at the first time (sampled every ``sticking_resolution`` seconds, then refined by
root finding) when either rate changes sign.  A stuck state costs no
right-hand-side evaluations, so no integration can chatter or hang there.

Naive switching
---------------
``switching="naive"`` is the contrast the book needs: no events, no sticking
rule, the force's branch chosen from the current state at every evaluation (a
plain if-statement).  Such a run chatters on ``x_C' = 0``; ``max_nfev`` bounds
it, and hitting the bound raises an :class:`IntegrationError` that carries the
partial result.

Branch guard
------------
Where det Phi_z of the model's partition changes sign, a redundant-coordinate
formulation either passes a dead position (Phi_s keeps full rank: fine) or
jumps to another assembly branch near a configuration where Phi_s nearly loses
rank.  At every such crossing simulate() computes the Kantorovich number
``h = sigma_max(Phi_s) |f| / sigma_min(Phi_s)^2``: Newton's method from the
state converges to a unique nearby solution when h < 1/2 (sigma_max standing
for the Lipschitz constant of Phi_s, which it matches for constraints made of
lengths times sines and cosines).  Above :data:`BRANCH_LIMIT` the state is no
longer unambiguously on one branch, and the run stops with a
:class:`SingularConfigurationError`.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import BDF, DOP853, LSODA, RK23, RK45, OdeSolver, Radau, solve_ivp
from scipy.optimize import brentq

from ..errors import InputError, IntegrationError, SingularConfigurationError
from ..formulations import Baumgarte, Formulation
from ..formulations.closed_form import partition_determinant
from ..kinematics import InitialState
from . import dop853 as ode_dop853

__all__ = ["simulate", "SimulationResult", "SwitchEvent", "SOLVER_METHODS", "SWITCHING", "BRANCH_LIMIT"]

#: The methods simulate() accepts by name: solve_ivp's, and "ode.dop853", the compiled DOP853
#: of scipy.integrate.ode with events added by :mod:`closedloop.simulation.dop853`.  An OdeSolver
#: subclass is accepted too.
SOLVER_METHODS = ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA", ode_dop853.METHOD)
#: How switched forces are handled: with events and the sticking rule, or naively.
SWITCHING = ("events", "naive")
#: Kantorovich number above which a crossing of det Phi_z = 0 is refused (see "Branch guard").
BRANCH_LIMIT = 0.01
#: Constraint error above which an initial state is refused as inconsistent.
INITIAL_TOLERANCE = 1e-8
#: Default bound on the accepted steps of one simulate() call: a run that needs more fails clearly.
MAX_STEPS = 1_000_000
_SOLVER_CLASSES = {"RK45": RK45, "RK23": RK23, "DOP853": DOP853, "Radau": Radau, "BDF": BDF, "LSODA": LSODA}
_IMPLICIT = ("Radau", "BDF", "LSODA")
_MIN_PROGRESS = 1e-12   # a segment shorter than this (s) makes no progress


@dataclass(frozen=True)
class SwitchEvent:
    """One stop at a switching surface: when, which switch, and what happened.

    ``action`` is one of ``"crossed"``, ``"turned back"``, ``"stuck"``, ``"released"``.
    """

    t: float
    switch: str
    action: str


@dataclass
class SimulationResult:
    """What :func:`simulate` computed.

    Attributes
    ----------
    t : ndarray, shape (N,)
        Output times.
    s, sd : ndarray, shape (n, N)
        Coordinates and velocities (rows in the order of the model's coordinates).
    constraint_error : ndarray, shape (N,)
        ``|f| = sqrt(sum f_i^2)`` of (32).
    velocity_constraint_error : ndarray, shape (N,)
        ``|f'| = |Phi_s s'|`` of (9).
    multipliers : ndarray, shape (r, N), or None
        lambda of (5), only when asked for.
    nfev : int
        Right-hand-side evaluations, summed over all segments.
    cpu_time : float
        Process time of the run in seconds (integration, switching, output).
    switch_events : list of SwitchEvent
    sticking_intervals : list of (float, float)
        Time intervals spent stuck (see the module's sticking rule).
    stopped_at : float or None
        Where ``stop_when`` ended the run early, else None.
    partition_singularities : list of float
        Times where det Phi_z of the model's partition changed sign (dead
        positions passed by a redundant-coordinate formulation).
    switching : str
        "events" or "naive" (see the module's notes).
    formulation, method : str
    rtol, atol : float
    coordinate_names : tuple of str
    step_sizes : ndarray, shape (n_steps,)
        Every accepted step of the integrator [s], in order, over all segments.
    work : ndarray, shape (N,), or None
        Only with ``work=True``: the work W(t) [J] done since ``t_start`` by the
        non-conservative generalised forces tau of (5) (the model's smooth
        forces and the switched force), integrated with the state.
    """

    t: np.ndarray
    s: np.ndarray
    sd: np.ndarray
    constraint_error: np.ndarray
    velocity_constraint_error: np.ndarray
    multipliers: np.ndarray | None
    nfev: int
    cpu_time: float
    switch_events: list = field(default_factory=list)
    sticking_intervals: list = field(default_factory=list)
    stopped_at: float | None = None
    partition_singularities: list = field(default_factory=list)
    switching: str = "events"
    formulation: str = ""
    method: str = ""
    rtol: float = math.nan
    atol: float = math.nan
    coordinate_names: tuple = ()
    step_sizes: np.ndarray = field(default_factory=lambda: np.empty(0))
    work: np.ndarray | None = None

    @property
    def n_steps(self) -> int:
        """Accepted integration steps, summed over all segments."""
        return int(self.step_sizes.size)

    @property
    def max_constraint_error(self) -> float:
        """The maximum of (32) over the run."""
        return float(np.max(self.constraint_error))

    def coordinate(self, name):
        """The row of ``s`` for the coordinate called ``name``."""
        return self.s[self.coordinate_names.index(name)]

    def velocity(self, name):
        """The row of ``sd`` for the coordinate called ``name``."""
        return self.sd[self.coordinate_names.index(name)]


def _finite_and_positive(value):
    """True for a finite number > 0, or an array of them (a float is checked without numpy)."""
    if isinstance(value, float):
        return math.isfinite(value) and value > 0
    return bool(np.all(np.isfinite(value)) and np.all(np.asarray(value) > 0))


def _validate(system, initial_state, t_start, t_end, formulation, method, rtol, atol, t_eval,
              sticking_resolution, options, switching="events", max_nfev=None, max_steps=MAX_STEPS):
    for name, value in (("t_start", t_start), ("t_end", t_end)):
        if not (isinstance(value, (int, float, np.floating)) and math.isfinite(value)):
            raise InputError(f"{name}: must be a finite number, got {value!r}")
    if not t_end > t_start:
        raise InputError(f"t_end: must be > t_start = {t_start:g}, got {t_end:g}")
    for name, value in (("rtol", rtol), ("atol", atol), ("sticking_resolution", sticking_resolution)):
        if not _finite_and_positive(value):
            raise InputError(f"{name}: must be finite and > 0, got {value!r}")
    if not isinstance(formulation, Formulation):
        raise InputError(
            "formulation: expected a Formulation (Augmented, Baumgarte, Orthogonal, Minimal, NullSpace, "
            f"ClosedForm or Projected), got {formulation!r}"
        )
    formulation.check_method(method)
    if switching not in SWITCHING:
        raise InputError(f"switching: unknown {switching!r}; choose one of {', '.join(SWITCHING)}")
    if max_nfev is not None and not (isinstance(max_nfev, (int, np.integer)) and max_nfev > 0):
        raise InputError(f"max_nfev: must be a whole number > 0, got {max_nfev!r}")
    if not (isinstance(max_steps, (int, np.integer)) and max_steps >= 1):
        raise InputError(f"max_steps: must be an integer >= 1, got {max_steps!r}")
    if method == ode_dop853.METHOD:
        if switching == "naive":
            raise InputError(f"method: switching='naive' runs on solve_ivp; choose one of "
                             f"{', '.join(SOLVER_METHODS[:-1])}")
        if not formulation.guards_partition:
            raise InputError(
                f"method: {method} has no dense output for the branch guard, so it takes only formulations "
                "that cannot cross det Phi_z = 0 unnoticed (ClosedForm, Orthogonal, Minimal); use a "
                f"solve_ivp method with {type(formulation).__name__}"
            )
    if not (method in SOLVER_METHODS or (isinstance(method, type) and issubclass(method, OdeSolver))):
        raise InputError(f"method: unknown {method!r}; choose one of {', '.join(SOLVER_METHODS)}")
    reserved = {"events", "dense_output", "args", "vectorized"} & set(options)
    if reserved:
        raise InputError(f"solver options: {sorted(reserved)} are managed by simulate()")
    if method == ode_dop853.METHOD:
        unknown = set(options) - set(ode_dop853.ALLOWED_OPTIONS)
        if unknown:
            raise InputError(f"solver options: {sorted(unknown)} are not taken by {method}; it takes "
                             f"{', '.join(ode_dop853.ALLOWED_OPTIONS)}")
    if not isinstance(initial_state, InitialState):
        raise InputError("initial_state: expected an InitialState (see consistent_initial_state)")
    s0, sd0 = initial_state.s, initial_state.sd
    if s0.shape != (system.n,) or sd0.shape != (system.n,):
        raise InputError(f"initial_state: need {system.n} coordinates and {system.n} velocities")
    if not (np.isfinite(s0).all() and np.isfinite(sd0).all()):
        raise InputError("initial_state: coordinates and velocities must be finite")
    f0, Phi0 = system.constraints_and_jacobian(s0)
    scale = 1.0 + np.abs(s0).max()
    velocity = Phi0 @ sd0
    errors = (math.sqrt(f0 @ f0), math.sqrt(velocity @ velocity))       # the 2-norms, as np.linalg.norm
    if errors[0] > INITIAL_TOLERANCE * scale or errors[1] > INITIAL_TOLERANCE * (1.0 + np.abs(sd0).max()):
        raise InputError(
            f"initial_state: not consistent (|f| = {errors[0]:.3g}, |f'| = {errors[1]:.3g}, allowed "
            f"<= {INITIAL_TOLERANCE:g}); build it with consistent_initial_state"
        )
    if t_eval is not None:
        t_eval = np.asarray(t_eval, dtype=float)
        if t_eval.ndim != 1 or np.any(np.diff(t_eval) <= 0) or t_eval[0] < t_start or t_eval[-1] > t_end:
            raise InputError(f"t_eval: must increase strictly within [{t_start:g}, {t_end:g}]")
    return t_eval


def simulate(system, initial_state, t_end=20.0, *, t_start=0.0, formulation=None, method="RK45",
             rtol=1e-9, atol=1e-9, t_eval=None, multipliers=False, stop_when=None,
             sticking_resolution=0.01, max_segments=100_000, switching="events", max_nfev=None,
             max_steps=MAX_STEPS, work=False, **options):
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
        Output times; default: the solver's own steps.
    multipliers : bool, optional
        Also compute lambda of (5) at the output times.
    stop_when : callable, optional
        ``stop_when(t, s, sd) -> float``: the run ends early, at the time this
        crosses zero upward (e.g. a speed limit for a run-away motion).  The
        result's ``stopped_at`` is then that time.  It is not evaluated
        while the mechanism is stuck (its state is then constant).
    sticking_resolution : float, optional
        Sampling interval (s) for the release of a stuck state.
    max_segments : int, optional
        Bound on the number of segments between switches.
    switching : {"events", "naive"}, optional
        "events" (default): stop at every switch and apply the sticking rule.
        "naive": choose the force's branch from the state at every evaluation,
        with no events (a contrast that chatters; see the module's notes).
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
        ``work``), for the energy balance ``Delta(T + Pi) = W``.
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
        formulations and the branch guard above): the message names the time
        and the condition number that went bad.
    """
    formulation = Baumgarte() if formulation is None else formulation
    t_eval = _validate(system, initial_state, t_start, t_end, formulation, method, rtol, atol,
                       t_eval, sticking_resolution, options, switching, max_nfev, max_steps)
    start = time.process_time()
    if stop_when is not None and not callable(stop_when):
        raise InputError("stop_when: expected a callable stop_when(t, s, sd) -> float")
    run = _Run(system, formulation, method, rtol, atol, t_eval, t_end, sticking_resolution, options,
               stop_when, max_nfev, _StepBudget(max_steps), work)
    if switching == "naive":
        message = run.integrate_naive(t_start, initial_state.s, initial_state.sd)
        if message is not None:
            error = IntegrationError(message)
            error.result = _result(system, formulation, run, start, False, switching)
            raise error
    else:
        run.integrate(t_start, initial_state.s, initial_state.sd, max_segments)
    return _result(system, formulation, run, start, multipliers, switching)


def _result(system, formulation, run, start, multipliers, switching):
    """The SimulationResult of a finished (or, for a naive run, capped) run."""
    t, s, sd, modes, work_done = run.outputs()
    f_norm, fd_norm = system.constraint_errors(s, sd)
    cpu_time = time.process_time() - start
    lam = _multipliers(system, formulation, t, s, sd, modes, run) if multipliers else None
    return SimulationResult(
        t=t, s=s, sd=sd, constraint_error=f_norm, velocity_constraint_error=fd_norm,
        multipliers=lam, nfev=run.nfev, cpu_time=cpu_time, switch_events=run.switch_events,
        sticking_intervals=run.sticking_intervals, stopped_at=run.stopped_at,
        partition_singularities=run.partition_singularities, switching=switching, formulation=formulation.name,
        method=run.method if isinstance(run.method, str) else run.method.__name__, rtol=run.rtol, atol=run.atol,
        coordinate_names=tuple(str(c) for c in system.model.coordinates),
        step_sizes=np.asarray(run.budget.steps, dtype=float), work=work_done,
    )


class _StepBudget:
    """Accepted steps of one simulate() call: their sizes, and the bound max_steps."""

    def __init__(self, max_steps):
        self.max_steps = max_steps
        self.steps = []
        self.t = None             # time of the last accepted step
        self.exhausted = False

    def solver(self, method):
        """The solve_ivp method as an OdeSolver subclass that reports every accepted step here."""
        base = _SOLVER_CLASSES[method] if isinstance(method, str) else method
        budget = self

        class Counted(base):
            def _step_impl(self):
                t_before = self.t
                success, message = super()._step_impl()
                if success and self.t != t_before:
                    budget.steps.append(abs(self.t - t_before))
                    budget.t = self.t
                    if len(budget.steps) >= budget.max_steps and self.t != self.t_bound:
                        budget.exhausted = True
                        return False, f"max_steps = {budget.max_steps} reached"
                return success, message

        Counted.__name__ = Counted.__qualname__ = base.__name__
        return Counted

    @property
    def last_step(self):
        return self.steps[-1] if self.steps else math.nan


class _BudgetExceeded(Exception):
    """Raised inside the right-hand side when max_nfev is used up."""


class _Run:
    """The segment loop of one simulate() call (no state survives the call)."""

    def __init__(self, system, formulation, method, rtol, atol, t_eval, t_end, resolution, options,
                 stop_when=None, max_nfev=None, budget=None, work=False):
        self.system, self.formulation, self.method = system, formulation, method
        self.method_name = method if isinstance(method, str) else method.__name__
        self.budget = _StepBudget(MAX_STEPS) if budget is None else budget
        self.track_work, self.work_done = bool(work), 0.0
        self.rtol, self.atol, self.options = rtol, atol, options
        self.t_eval, self.t_end, self.resolution = t_eval, t_end, resolution
        self.force = system.force
        self.names = self.force.switch_names if self.force is not None else ()
        self.nfev, self.max_nfev = 0, max_nfev
        self.partition_singularities = []
        self.stop_when, self.stopped_at = stop_when, None
        self.switch_events, self.sticking_intervals = [], []
        self._pieces = []          # (t, s, sd, mode, stuck, work or None) per segment
        self._next_output = 0      # index into t_eval

    # -- mode decisions ---------------------------------------------------------
    def _accelerations(self, t, s, sd, mode):
        """s'' of (12) on branch ``mode``.

        With ClosedForm, whose closed form is generated anyway, from that closed
        form with alpha = beta = 0 (the same s'' of (12), without assembling and
        solving the augmented matrix); else, or where det Phi_z = 0, from the
        augmented solve.
        """
        fast = self.formulation.switch_accelerations(self.system, mode)
        if fast is not None:
            try:
                return fast(t, s, sd)
            except SingularConfigurationError:
                pass
        return self.system.constrained_accelerations(t, s, sd, mode)[0]

    def _side_rates(self, t, s, sd, mode, i):
        """dh_i/dt along the constrained motion (12) with switch i off and on: ``(off, on)``."""
        h = self.force.switching_functions
        eps = 1e-7
        h_now, s_ahead = h(t, s, sd)[i], s + eps * sd          # the same on both sides
        off, on = ((h(t + eps, s_ahead, sd + eps * self._accelerations(t, s, sd, branch))[i] - h_now) / eps
                   for branch in (mode[:i] + (False,) + mode[i + 1:], mode[:i] + (True,) + mode[i + 1:]))
        return off, on

    def _decide(self, t, s, sd, mode, i):
        """The branch of switch i at a state on its surface: (new mode, action)."""
        off, on = self._side_rates(t, s, sd, mode, i)
        if off > 0 and on > 0:
            side = True
        elif off < 0 and on < 0:
            side = False
        elif off > 0 > on:                                # both sides push onto the surface
            if not self.force.can_stick[i]:
                raise IntegrationError(
                    f"at t = {t:.6g} s the state slides along switch {self.names[i]!r}, which is "
                    "not declared able to stick; regularise the force or declare can_stick"
                )
            return mode, "stuck"
        else:                                              # grazing or repelling: turn back
            side = mode[i]
        action = "crossed" if side != mode[i] else "turned back"
        return mode[:i] + (side,) + mode[i + 1:], action

    def _initial_mode(self, t, s, sd):
        h = self.force.switching_functions(t, s, sd)
        mode = tuple(bool(v > 0) for v in h)
        scale = 1.0 + np.max(np.abs(np.concatenate((s, sd))))
        for i, v in enumerate(h):
            if abs(v) <= 1e-12 * scale:                    # starts on a surface
                mode, action = self._decide(t, s, sd, mode, i)
                if action == "stuck":
                    return mode, i
        return mode, None

    # -- the loop ---------------------------------------------------------------
    def integrate(self, t, s, sd, max_segments):
        if self.force is None or not self.names:
            mode, stuck = (), None
        else:
            mode, stuck = self._initial_mode(t, s, sd)
        stalled = 0
        for _ in range(max_segments):
            if stuck is not None:
                t, s, sd, mode, stuck = self._stick(t, s, mode, stuck)
                if t >= self.t_end:
                    return
                continue
            t_new, s, sd, event = self._segment(t, s, sd, mode)
            stalled = stalled + 1 if t_new - t < _MIN_PROGRESS * max(1.0, abs(t)) else 0
            t = t_new
            if stalled > 50:
                raise IntegrationError(
                    f"the state chatters on switch {self.names[event]!r} at t = {t:.6g} s: 50 stops "
                    "without progress; loosen rtol or regularise the force"
                )
            if event is None:
                return
            if event == len(self.names):                   # stop_when fired
                self.stopped_at = t
                return
            mode, action = self._decide(t, s, sd, mode, event)
            self.switch_events.append(SwitchEvent(t, self.names[event], action))
            if action == "stuck":
                stuck = event
        raise IntegrationError(
            f"more than {max_segments} switch segments before t = {t:.6g} s; raise max_segments "
            "or check the force for chattering"
        )

    def _start(self, s0, sd0, mode):
        """``(y0, unpack, rhs)`` of a segment on branch ``mode``, with the work state if asked for."""
        system, formulation = self.system, self.formulation
        y0 = formulation.pack(system, s0, sd0)
        unpack = formulation.unpacker(system)
        unpack.seed(s0)
        rhs = formulation.make_rhs(system, mode, unpack)
        if self.track_work:                         # one more state: W' = tau . s'
            y0, rhs, unpack = self._with_work(y0, rhs, unpack, mode)
        return y0, unpack, rhs

    def _segment(self, t0, s0, sd0, mode):
        """Integrate on one branch until t_end or the next switch."""
        if self.method == ode_dop853.METHOD:
            return self._compiled_segment(t0, s0, sd0, mode)
        system, formulation = self.system, self.formulation
        y0, unpack, rhs = self._start(s0, sd0, mode)
        events = []
        for i in range(len(self.names)):
            events.append(self._event(unpack, i, mode[i]))
        if self.stop_when is not None:
            events.append(self._stop_event(unpack))
        terminal = len(events)
        if not formulation.guards_branch:           # else the formulation guards its branch itself
            events.append(self._branch_event(unpack))
        t_eval = None
        if self.t_eval is not None:
            t_eval = self.t_eval[self._next_output:]
            t_eval = t_eval[t_eval >= t0]
        reached = [t0]                              # the last time the right-hand side was evaluated

        budget = math.inf if self.max_nfev is None else self.max_nfev - self.nfev
        count = [0]
        overflow = []                               # (t, message) where the right-hand side overflowed

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

        try:
            base = formulation.integrator(system, self.method)   # Projected resets the state after each step
            sol = solve_ivp(guarded_rhs, (t0, self.t_end), y0, method=self.budget.solver(base),
                            rtol=self.rtol, atol=self.atol, t_eval=t_eval, events=events or None,
                            **self.options)
        except _BudgetExceeded:
            raise IntegrationError(
                f"{self.method_name} used up max_nfev = {self.max_nfev} right-hand-side evaluations at "
                f"t = {reached[0]:.6g} s of {self.t_end:g} s; loosen rtol, or raise max_nfev"
            ) from None
        except ValueError as error:
            if "different signs" not in str(error):
                raise
            t = t0 if self.budget.t is None or self.budget.t < t0 else self.budget.t
            raise IntegrationError(
                f"{self.method_name} could not locate a switch ({', '.join(self.names)}) in the step after "
                f"t = {t:.6g} s (h = {self.budget.last_step:.3g} s): a switching function changed sign "
                "between the ends of the step but not along its interpolant, so the step is too long "
                "for the motion; try tighter tolerances, a max_step, or another formulation"
            ) from None
        self.nfev += sol.nfev
        if terminal < len(events):
            self._check_crossings(sol.t_events[terminal], sol.y_events[terminal], unpack)
        if sol.status == -1:
            raise IntegrationError(self._failure_message(sol.message, t0, overflow))
        t_out = np.asarray(sol.t, dtype=float)          # solve_ivp gives lists when t_eval is empty
        y_out = np.asarray(sol.y, dtype=float).reshape(y0.size, t_out.size)
        self._check_finite(t_out, y_out)
        outputs = formulation.unpacker(system)          # marches from the start, Newton's guess close by
        outputs.seed(s0)
        self._store(t_out, y_out, outputs, mode, t0)
        if sol.status == 0:                             # reached t_end: no end state is needed
            return self.t_end, None, None, None
        times = [te[0] if te.size else np.inf for te in sol.t_events[:terminal]]
        event = int(np.argmin(times))
        t_end, y_end = sol.t_events[event][0], sol.y_events[event][0]
        if self.track_work:
            self.work_done = float(y_end[-1])
        s_end, sd_end = unpack(y_end, t_end)
        return t_end, s_end, sd_end, event

    def _check_finite(self, t_out, y_out):
        if np.isfinite(y_out).all():
            return
        bad = ~np.all(np.isfinite(y_out), axis=0)
        if np.any(bad):
            k = int(np.argmax(bad))
            names = self._state_names(y_out.shape[0])
            which = [name for name, v in zip(names, y_out[:, k]) if not np.isfinite(v)]
            raise IntegrationError(
                f"the state became non-finite at t = {t_out[k]:.6g} s with {self.method_name} "
                f"({', '.join(which)} = {y_out[names.index(which[0]), k]}); {self._advice()}"
            )

    def _check_partition(self, segment, t0):
        """ode.dop853 has no events for det Phi_z: refuse a path whose step ends straddle a zero.

        R of (20), and so ClosedForm and Orthogonal, does not exist where det Phi_z = 0;
        a step that jumps across such a point has left the configurations R describes.
        """
        system = self.system
        determinant = partition_determinant(system)            # generated once per system
        if determinant is not None:
            det = determinant(segment.step_ends[:system.n])
        else:
            Phi_z = system.constraints_and_jacobian_many(segment.step_ends[:system.n])[1][:, system.z_index]
            det = np.linalg.det(np.moveaxis(Phi_z, 2, 0))
        if (det > 0.0).all() or (det < 0.0).all():         # one sign along the whole segment
            return
        flips = np.nonzero(np.sign(det[1:]) * np.sign(det[:-1]) < 0)[0]
        if flips.size:
            times = np.concatenate(([t0], t0 + np.cumsum(segment.steps), [segment.t_stop]))
            k = int(flips[0])
            raise SingularConfigurationError(
                f"det Phi_z changed sign between t = {times[k]:.6g} s and t = {times[k + 1]:.6g} s with "
                f"{self.method_name}: the path crossed a configuration where R of (20) does not exist, "
                "and this method cannot locate it or apply the branch guard; use a solve_ivp method "
                "(the branch guard), or the NullSpace formulation"
            )

    def _with_work(self, y0, rhs, unpack, mode):
        """Append the work W to the state: ``W' = tau(t, s, s') . s'`` on branch ``mode``."""
        system = self.system

        def rhs_with_work(t, y):
            x = y[:-1]
            s, sd = unpack(x, t)
            power = system.applied_forces(t, s, sd, mode) @ sd
            return np.append(rhs(t, x), power)

        def unpack_with_work(y, t=None):
            return unpack(y[:-1], t)

        unpack_with_work.seed = unpack.seed
        return np.append(y0, self.work_done), rhs_with_work, unpack_with_work

    def _state_names(self, size):
        names = self.formulation.state_names(self.system)
        return names + ["W"] * (size - len(names))

    def _advice(self):
        """What to try instead, for an integration that failed."""
        tries = []
        if self.method_name not in _IMPLICIT:
            tries.append("an implicit method (Radau, BDF or LSODA)")
        gains = self.formulation.gains
        if gains is not None and max(gains) > 20.0:
            tries.append(f"smaller Baumgarte gains than alpha = {gains[0]:g}, beta = {gains[1]:g} "
                         "(the paper's range is 1 to 20)")
        tries.append("looser tolerances than rtol = {:g}, atol = {:g}".format(
            np.max(self.rtol), np.max(self.atol)))
        return "try " + ", or ".join(tries)

    def _failure_message(self, message, t0, overflow):
        """The IntegrationError text for a solve_ivp failure: time, quantity, what to try."""
        budget = self.budget
        t = t0 if budget.t is None or budget.t < t0 else budget.t
        h = budget.last_step
        if budget.exhausted:
            text = (f"{self.method_name} reached max_steps = {budget.max_steps} at t = {t:.6g} s of "
                    f"t_end = {self.t_end:g} s (last step size h = {h:.3g} s, mean "
                    f"{np.mean(budget.steps[-100:]):.3g} s over the last 100 steps): the problem is stiff "
                    "for this method, or the run too long")
            advice = self._advice() + ", or raise max_steps"
        elif message and "step size is less than spacing" in message:
            text = (f"{self.method_name} failed at t = {t:.6g} s: the step size underflowed (it must stay "
                    f"above 10 ulp(t) = {10 * np.spacing(abs(t)):.3g} s; the last accepted step was "
                    f"h = {h:.3g} s)")
            advice = self._advice()
        else:
            text = f"{self.method_name} failed at t = {t:.6g} s (last step h = {h:.3g} s): {message}"
            advice = self._advice()
        if overflow:
            text += (f"; the right-hand side overflowed ({overflow[-1][1]}) at t = {overflow[-1][0]:.6g} s, "
                     "the accelerations are beyond the range of floating-point numbers")
        return f"{text}; {advice}"

    def _compiled_segment(self, t0, s0, sd0, mode):
        """_segment with the compiled DOP853 of scipy.integrate.ode (see closedloop.simulation.dop853)."""
        system, formulation = self.system, self.formulation
        y0, unpack, rhs = self._start(s0, sd0, mode)
        h = self.force.switching_functions if self.names else None
        stop_when = self.stop_when

        if stop_when is None and h is not None:        # the common case, called after every step
            def switching(t, y):
                s, sd = unpack(y, t)
                values = h(t, s, sd)
                return values.tolist() if isinstance(values, np.ndarray) else list(values)
        else:
            def switching(t, y):
                if h is None and stop_when is None:
                    return ()
                s, sd = unpack(y, t)
                values = h(t, s, sd) if h is not None else []
                values = values.tolist() if isinstance(values, np.ndarray) else list(values)
                return values + [stop_when(t, s, sd)] if stop_when is not None else values

        directions = [-1.0 if on else 1.0 for on in mode[:len(self.names)]]
        if stop_when is not None:
            directions.append(1.0)
        outputs = None
        if self.t_eval is not None:
            outputs = self.t_eval[self._next_output:]
            outputs = outputs[outputs >= t0]
        options = dict(self.options)
        first_step = options.pop("first_step", None) if not self._pieces else None
        budget = math.inf if self.max_nfev is None else self.max_nfev - self.nfev
        try:
            segment = ode_dop853.integrate_segment(
                rhs, t0, y0, self.t_end, rtol=self.rtol, atol=self.atol, switching=switching,
                directions=directions, outputs=outputs, max_nfev=budget,
                nsteps=options.pop("nsteps", max(1, min(ode_dop853.DEFAULT_NSTEPS,
                                                        self.budget.max_steps - len(self.budget.steps)))),
                first_step=first_step if first_step is not None else getattr(self, "_last_step", 0.0),
                **options)
        except ode_dop853.BudgetExceeded as exceeded:
            raise IntegrationError(
                f"{self.method} used up max_nfev = {self.max_nfev} right-hand-side evaluations at "
                f"t = {exceeded.t:.6g} s of {self.t_end:g} s; loosen rtol, or raise max_nfev"
            ) from None
        self.nfev += segment.nfev
        self._last_step = segment.last_step
        self.budget.steps.extend(segment.steps)
        self.budget.t = segment.t_stop
        self._check_finite(segment.t, segment.y)
        if not formulation.guards_branch:                   # else the formulation guards it itself
            self._check_partition(segment, t0)
        outputs_unpack = formulation.unpacker(system)
        outputs_unpack.seed(s0)
        self._store(segment.t, segment.y, outputs_unpack, mode, t0)
        if segment.event is None:
            return self.t_end, None, None, None
        if self.track_work:
            self.work_done = float(segment.y_stop[-1])
        s_end, sd_end = unpack(segment.y_stop, segment.t_stop)
        return segment.t_stop, s_end, sd_end, segment.event

    def _event(self, unpack, i, on):
        h = self.force.switching_functions

        def event(t, y):
            s, sd = unpack(y, t)
            return h(t, s, sd)[i]

        event.terminal = True
        event.direction = -1.0 if on else 1.0
        return event

    def _branch_event(self, unpack):
        """det Phi_z of the model's partition: it changes sign at a singular configuration of (20)."""
        zi = self.system.z_index

        def event(t, y):
            return np.linalg.det(self.system.jacobian(unpack(y, t)[0])[:, zi])

        return event

    def _check_crossings(self, times, states, unpack):
        """The branch guard (see the module's notes) at each zero of det Phi_z."""
        for t, y in zip(times, states):
            f, Phi = self.system.constraints_and_jacobian(unpack(y, t)[0])
            singular_values = np.linalg.svd(Phi, compute_uv=False)
            largest, smallest, error = singular_values[0], singular_values[-1], np.linalg.norm(f)
            kantorovich = math.inf if smallest == 0 else largest * error / smallest**2
            if kantorovich > BRANCH_LIMIT:
                raise SingularConfigurationError(
                    f"the path crossed a singular configuration of Phi_z at t = {t:.6g} s where Phi_s nearly "
                    f"loses rank (cond(Phi_s) = {largest / smallest:.3g}, |f| = {error:.3g}, Kantorovich "
                    f"number {kantorovich:.3g} > {BRANCH_LIMIT:g}): the constraint error is as large as the "
                    "distance between assembly branches, so the run may have changed branch; tighten rtol "
                    "and atol (at a bifurcation itself no formulation can choose the branch)"
                )
            self.partition_singularities.append(float(t))

    def _stop_event(self, unpack):
        def event(t, y):
            return self.stop_when(t, *unpack(y, t))

        event.terminal = True
        event.direction = 1.0
        return event

    def _store(self, t, y, unpack, mode, t0):
        if self.t_eval is not None:
            self._next_output += t.size
        elif self._pieces and t.size and t[0] == t0:
            t, y = t[1:], y[:, 1:]           # the first point repeats the last segment's end
        if t.size == 0:
            return
        work = None
        if self.track_work:
            y, work = y[:-1], y[-1]
        pairs = [unpack(y[:, k], t[k]) for k in range(t.size)]
        s = np.array([p[0] for p in pairs]).T
        sd = np.array([p[1] for p in pairs]).T
        self._pieces.append((t, s, sd, mode, None, work))

    def _stick(self, t0, s, mode, i):
        """Hold the mechanism at rest on switch i until it is released (the sticking rule)."""
        system = self.system
        if system.f != 1:
            raise IntegrationError(
                f"the state sticks on switch {self.names[i]!r} at t = {t0:.6g} s; the sticking rule "
                f"holds the mechanism at rest, which is only valid for one degree of freedom (f = {system.f})"
            )
        sd = np.zeros(system.n)

        def margin(t):                   # > 0 while the holding force lies between the branches
            off, on = self._side_rates(t, s, sd, mode, i)
            return min(off, -on)

        t_release, previous = None, t0             # margin(t0) > 0: _decide found off > 0 > on
        grid = np.arange(t0 + self.resolution, self.t_end + self.resolution, self.resolution)
        for t in np.minimum(grid, self.t_end):
            if margin(t) <= 0:
                t_release, past = brentq(margin, previous, t, xtol=1e-12), t
                break
            previous = t
        t_stop = self.t_end if t_release is None else t_release
        self.sticking_intervals.append((t0, t_stop))
        if self.t_eval is not None:
            rest = self.t_eval[self._next_output:]
            times = rest[rest <= t_stop]
            self._next_output += times.size
        else:
            times = np.array([t0, t_stop])
        if times.size:
            held = mode[:i] + (False,) + mode[i + 1:]     # the force's free branch, plus the holding force
            work = np.full(times.size, self.work_done) if self.track_work else None   # at rest: no power
            self._pieces.append((times, np.repeat(s[:, None], times.size, 1),
                                 np.zeros((system.n, times.size)), held, i, work))
        if t_release is None:
            return self.t_end, s, sd, mode, None
        # The side is read just past the root (at the grid point where the margin is <= 0):
        # at the root itself the rate that ends the sticking is zero to round-off.
        off, on = self._side_rates(past, s, sd, mode, i)
        side = bool(off > 0)                       # off <= 0: the free motion turns back (h < 0)
        self.switch_events.append(SwitchEvent(t_release, self.names[i], "released"))
        return t_release, s, sd, mode[:i] + (side,) + mode[i + 1:], None

    def integrate_naive(self, t0, s0, sd0):
        """One integration, the force's branch chosen from the state at each evaluation.

        Steps the OdeSolver by hand so that a run bounded by ``max_nfev`` keeps
        what it computed.  Returns None when t_end is reached, else the message
        of the error to raise.
        """
        from scipy.integrate._ivp.ivp import METHODS

        system, formulation = self.system, self.formulation
        unpack = formulation.unpacker(system)
        unpack.seed(s0)
        rhs_on = {}
        changes = np.zeros(len(self.names), dtype=int)
        last_mode = [None]

        def rhs(t, y):
            self.nfev += 1
            mode = ()
            if self.force is not None:
                mode = self.force.mode_at(t, *unpack(y, t))
                if last_mode[0] is not None:
                    changes[:] += np.array(mode) != np.array(last_mode[0])
                last_mode[0] = mode
            if mode not in rhs_on:
                rhs_on[mode] = formulation.make_rhs(system, mode, unpack)
            return rhs_on[mode](t, y)

        solver_class = METHODS[self.method] if isinstance(self.method, str) else self.method
        solver = solver_class(rhs, t0, formulation.pack(system, s0, sd0), self.t_end, rtol=self.rtol,
                              atol=self.atol, **self.options)
        if self.t_eval is None:
            times, states = [t0], [solver.y.copy()]
        else:
            first = self.t_eval[self.t_eval <= t0]
            times, states = list(first), [solver.y.copy()] * first.size
        message = None
        while solver.status == "running":
            if self.max_nfev is not None and self.nfev >= self.max_nfev:
                busiest = int(np.argmax(changes)) if changes.size else None
                where = (f"; the force switched {changes[busiest]} times on {self.names[busiest]!r} "
                         "(chattering)" if busiest is not None and changes[busiest] else "")
                message = (f"naive switching used up max_nfev = {self.max_nfev} right-hand-side evaluations "
                           f"at t = {solver.t:.6g} s of {self.t_end:g} s, last step {solver.step_size:.3g} s"
                           f"{where}; use switching='events'")
                break
            solver.step()
            if solver.status == "failed":
                message = (f"{self.method} failed at t = {solver.t:.6g} s with naive switching "
                           f"(step size {solver.step_size:.3g} s); use switching='events'")
                break
            if self.t_eval is None:
                times.append(solver.t)
                states.append(solver.y.copy())
            else:                                  # the step's own interpolant, as solve_ivp does
                inside = self.t_eval[(self.t_eval > solver.t_old) & (self.t_eval <= solver.t)]
                if inside.size:
                    times.extend(inside)
                    states.extend(np.atleast_2d(solver.dense_output()(inside).T))
        t = np.array(times)
        y = np.array(states).reshape(t.size, -1).T
        outputs = formulation.unpacker(system)
        outputs.seed(s0)
        pairs = [outputs(y[:, k], t[k]) for k in range(t.size)]
        self._pieces.append((t, np.array([p[0] for p in pairs]).T, np.array([p[1] for p in pairs]).T,
                             None, None, None))
        return message

    def outputs(self):
        t = np.concatenate([p[0] for p in self._pieces])
        s = np.concatenate([p[1] for p in self._pieces], axis=1)
        sd = np.concatenate([p[2] for p in self._pieces], axis=1)
        modes = [(p[3], p[4]) for p in self._pieces for _ in range(p[0].size)]
        keep = np.concatenate(([True], np.diff(t) > 0))  # drop repeated times at segment joins
        work = np.concatenate([p[5] for p in self._pieces])[keep] if self.track_work else None
        return t[keep], s[:, keep], sd[:, keep], [m for m, k in zip(modes, keep) if k], work


def _multipliers(system, formulation, t, s, sd, modes, run):
    """lambda of (5) at each output point, from (8): Phi_s^T lambda = p1 - M s''.

    While stuck (s'' = 0), the holding force of the stuck switch is a further
    unknown acting along dh/ds', solved together with lambda.
    """
    lam = np.empty((system.r, t.size))
    h = system.force.switching_functions if system.force is not None else None
    for k in range(t.size):
        mode, stuck = modes[k]
        M, p1, f, Phi, gamma = system.dynamics(t[k], s[:, k], sd[:, k], mode)
        if stuck is None:
            sdd = formulation.accelerations(system, t[k], s[:, k], sd[:, k], mode)
            lam[:, k] = np.linalg.lstsq(Phi.T, p1 - M @ sdd, rcond=None)[0]
        else:
            eps = 1e-7
            direction = np.array([(h(t[k], s[:, k], sd[:, k] + eps * e)[stuck] - h(t[k], s[:, k], sd[:, k])[stuck]) / eps
                                  for e in np.eye(system.n)])
            A = np.column_stack((Phi.T, direction))
            lam[:, k] = np.linalg.lstsq(A, p1, rcond=None)[0][:system.r]
    return lam
