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
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import OdeSolver, solve_ivp
from scipy.optimize import brentq

from .errors import InputError, IntegrationError
from .formulations import Augmented, Baumgarte, Minimal, Orthogonal
from .kinematics import InitialState
from .projection import Projected

__all__ = ["simulate", "SimulationResult", "SwitchEvent", "SOLVER_METHODS"]

#: The solve_ivp methods simulate() accepts by name (an OdeSolver subclass is accepted too).
SOLVER_METHODS = ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA")
_FORMULATIONS = (Augmented, Baumgarte, Orthogonal, Minimal, Projected)
#: Constraint error above which an initial state is refused as inconsistent.
INITIAL_TOLERANCE = 1e-8
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
    formulation, method : str
    rtol, atol : float
    coordinate_names : tuple of str
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
    formulation: str = ""
    method: str = ""
    rtol: float = math.nan
    atol: float = math.nan
    coordinate_names: tuple = ()

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


def _validate(system, initial_state, t_start, t_end, formulation, method, rtol, atol, t_eval,
              sticking_resolution, options):
    for name, value in (("t_start", t_start), ("t_end", t_end)):
        if not (isinstance(value, (int, float, np.floating)) and math.isfinite(value)):
            raise InputError(f"{name}: must be a finite number, got {value!r}")
    if not t_end > t_start:
        raise InputError(f"t_end: must be > t_start = {t_start:g}, got {t_end:g}")
    for name, value in (("rtol", rtol), ("atol", atol), ("sticking_resolution", sticking_resolution)):
        if not (np.all(np.isfinite(value)) and np.all(np.asarray(value) > 0)):
            raise InputError(f"{name}: must be finite and > 0, got {value!r}")
    if not isinstance(formulation, _FORMULATIONS):
        raise InputError(f"formulation: expected Augmented, Baumgarte, Orthogonal, Minimal or Projected, "
                         f"got {formulation!r}")
    if not (method in SOLVER_METHODS or (isinstance(method, type) and issubclass(method, OdeSolver))):
        raise InputError(f"method: unknown {method!r}; choose one of {', '.join(SOLVER_METHODS)}")
    if isinstance(formulation, Projected):
        formulation.check_method(method)
    reserved = {"events", "dense_output", "args", "vectorized"} & set(options)
    if reserved:
        raise InputError(f"solver options: {sorted(reserved)} are managed by simulate()")
    if not isinstance(initial_state, InitialState):
        raise InputError("initial_state: expected an InitialState (see consistent_initial_state)")
    s0, sd0 = initial_state.s, initial_state.sd
    if s0.shape != (system.n,) or sd0.shape != (system.n,):
        raise InputError(f"initial_state: need {system.n} coordinates and {system.n} velocities")
    if not (np.all(np.isfinite(s0)) and np.all(np.isfinite(sd0))):
        raise InputError("initial_state: coordinates and velocities must be finite")
    f0, Phi0 = system.constraints_and_jacobian(s0)
    scale = 1.0 + np.max(np.abs(s0))
    errors = (np.linalg.norm(f0), np.linalg.norm(Phi0 @ sd0))
    if errors[0] > INITIAL_TOLERANCE * scale or errors[1] > INITIAL_TOLERANCE * (1.0 + np.max(np.abs(sd0))):
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
             sticking_resolution=0.01, max_segments=100_000, **options):
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
    formulation : Augmented, Baumgarte, Orthogonal, Minimal or Projected, optional
        Default ``Baumgarte(5, 5)``, Baumgarte's own choice.
    method : str or OdeSolver, optional
        Any solve_ivp method; default "RK45".  Projected takes only RK23, RK45
        and DOP853 (see :mod:`closedloop.projection`).
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
        If solve_ivp fails, the state stops being finite, or the state chatters
        on a switch: the message names the time.
    """
    formulation = Baumgarte() if formulation is None else formulation
    t_eval = _validate(system, initial_state, t_start, t_end, formulation, method, rtol, atol,
                       t_eval, sticking_resolution, options)
    start = time.process_time()
    if stop_when is not None and not callable(stop_when):
        raise InputError("stop_when: expected a callable stop_when(t, s, sd) -> float")
    run = _Run(system, formulation, method, rtol, atol, t_eval, t_end, sticking_resolution, options,
               stop_when)
    run.integrate(t_start, initial_state.s, initial_state.sd, max_segments)
    t, s, sd, modes = run.outputs()
    f_norm = np.empty(t.size)
    fd_norm = np.empty(t.size)
    for k in range(t.size):
        f, Phi = system.constraints_and_jacobian(s[:, k])
        f_norm[k] = np.linalg.norm(f)
        fd_norm[k] = np.linalg.norm(Phi @ sd[:, k])
    cpu_time = time.process_time() - start
    lam = _multipliers(system, formulation, t, s, sd, modes, run) if multipliers else None
    return SimulationResult(
        t=t, s=s, sd=sd, constraint_error=f_norm, velocity_constraint_error=fd_norm,
        multipliers=lam, nfev=run.nfev, cpu_time=cpu_time, switch_events=run.switch_events,
        sticking_intervals=run.sticking_intervals, stopped_at=run.stopped_at, formulation=formulation.name,
        method=method if isinstance(method, str) else method.__name__, rtol=rtol, atol=atol,
        coordinate_names=tuple(str(c) for c in system.model.coordinates),
    )


class _Run:
    """The segment loop of one simulate() call (no state survives the call)."""

    def __init__(self, system, formulation, method, rtol, atol, t_eval, t_end, resolution, options,
                 stop_when=None):
        self.system, self.formulation, self.method = system, formulation, method
        self.rtol, self.atol, self.options = rtol, atol, options
        self.t_eval, self.t_end, self.resolution = t_eval, t_end, resolution
        self.force = system.force
        self.names = self.force.switch_names if self.force is not None else ()
        self.nfev = 0
        self.stop_when, self.stopped_at = stop_when, None
        self.switch_events, self.sticking_intervals = [], []
        self._pieces = []          # (t, s, sd, mode, stuck) per segment
        self._next_output = 0      # index into t_eval

    # -- mode decisions ---------------------------------------------------------
    def _rate(self, t, s, sd, mode, i):
        """dh_i/dt along the constrained motion (12) on branch ``mode``."""
        sdd = self.system.constrained_accelerations(t, s, sd, mode)[0]
        h = self.force.switching_functions
        eps = 1e-7
        return (h(t + eps, s + eps * sd, sd + eps * sdd)[i] - h(t, s, sd)[i]) / eps

    def _side_rates(self, t, s, sd, mode, i):
        off = self._rate(t, s, sd, mode[:i] + (False,) + mode[i + 1:], i)
        on = self._rate(t, s, sd, mode[:i] + (True,) + mode[i + 1:], i)
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

    def _segment(self, t0, s0, sd0, mode):
        """Integrate on one branch until t_end or the next switch."""
        system, formulation = self.system, self.formulation
        y0 = formulation.pack(system, s0, sd0)
        unpack = formulation.unpacker(system)
        unpack.seed(s0)
        rhs = formulation.make_rhs(system, mode, unpack)
        events = []
        for i in range(len(self.names)):
            events.append(self._event(unpack, i, mode[i]))
        if self.stop_when is not None:
            events.append(self._stop_event(unpack))
        t_eval = None
        if self.t_eval is not None:
            t_eval = self.t_eval[self._next_output:]
            t_eval = t_eval[t_eval >= t0]
        reached = [t0]                              # the last time the right-hand side was evaluated

        def timed_rhs(t, y):
            reached[0] = t
            return rhs(t, y)

        integrator = getattr(formulation, "integrator", None)   # Projected resets the state after each step
        method = self.method if integrator is None else integrator(system, self.method)
        try:
            sol = solve_ivp(timed_rhs, (t0, self.t_end), y0, method=method, rtol=self.rtol,
                            atol=self.atol, t_eval=t_eval, events=events or None, **self.options)
        except ValueError as error:     # scipy's root finder: a switching function with no sign change
            raise IntegrationError(
                f"{self.method} could not locate a switch near t = {reached[0]:.6g} s ({error}); "
                "tighten rtol and atol"
            ) from None
        self.nfev += sol.nfev
        if sol.status == -1:
            raise IntegrationError(
                f"{self.method} failed near t = {reached[0]:.6g} s: {sol.message} Try an implicit "
                "method (Radau, BDF), looser tolerances, or smaller Baumgarte gains"
            )
        t_out = np.asarray(sol.t, dtype=float)          # solve_ivp gives lists when t_eval is empty
        y_out = np.asarray(sol.y, dtype=float).reshape(y0.size, t_out.size)
        bad = ~np.all(np.isfinite(y_out), axis=0)
        if np.any(bad):
            raise IntegrationError(
                f"the state became non-finite at t = {t_out[np.argmax(bad)]:.6g} s with {self.method}; "
                "try an implicit method (Radau, BDF) or smaller Baumgarte gains"
            )
        outputs = formulation.unpacker(system)          # marches from the start, Newton's guess close by
        outputs.seed(s0)
        self._store(t_out, y_out, outputs, mode, t0)
        if sol.status == 0:                             # reached t_end: no end state is needed
            return self.t_end, None, None, None
        times = [te[0] if te.size else np.inf for te in sol.t_events]
        event = int(np.argmin(times))
        t_end, y_end = sol.t_events[event][0], sol.y_events[event][0]
        s_end, sd_end = unpack(y_end, t_end)
        return t_end, s_end, sd_end, event

    def _event(self, unpack, i, on):
        h = self.force.switching_functions

        def event(t, y):
            s, sd = unpack(y, t)
            return h(t, s, sd)[i]

        event.terminal = True
        event.direction = -1.0 if on else 1.0
        return event

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
        pairs = [unpack(y[:, k], t[k]) for k in range(t.size)]
        s = np.array([p[0] for p in pairs]).T
        sd = np.array([p[1] for p in pairs]).T
        self._pieces.append((t, s, sd, mode, None))

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
            self._pieces.append((times, np.repeat(s[:, None], times.size, 1),
                                 np.zeros((system.n, times.size)), held, i))
        if t_release is None:
            return self.t_end, s, sd, mode, None
        # The side is read just past the root (at the grid point where the margin is <= 0):
        # at the root itself the rate that ends the sticking is zero to round-off.
        off, on = self._side_rates(past, s, sd, mode, i)
        side = bool(off > 0)                       # off <= 0: the free motion turns back (h < 0)
        self.switch_events.append(SwitchEvent(t_release, self.names[i], "released"))
        return t_release, s, sd, mode[:i] + (side,) + mode[i + 1:], None

    def outputs(self):
        t = np.concatenate([p[0] for p in self._pieces])
        s = np.concatenate([p[1] for p in self._pieces], axis=1)
        sd = np.concatenate([p[2] for p in self._pieces], axis=1)
        modes = [(p[3], p[4]) for p in self._pieces for _ in range(p[0].size)]
        keep = np.concatenate(([True], np.diff(t) > 0))  # drop repeated times at segment joins
        return t[keep], s[:, keep], sd[:, keep], [m for m, k in zip(modes, keep) if k]


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
