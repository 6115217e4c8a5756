"""The options of one simulate() call: checked once, before any integration, and then frozen."""

from __future__ import annotations

import difflib
import math
import types
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..formulations import REGISTRY, Formulation
from ..kinematics import initial_state_arrays
from ..linalg import null_space_basis
from ..methods import IMPLICIT_METHODS, SOLVER_METHODS
from ..model import System
from ..validation import (finite_array, finite_number, flag, instance_of, is_real, output_times, positive_integer,
                          shown, shown_array)
from . import dop853
from .switching import MIN_PROGRESS, no_progress
from .work import WORK_NAME, state_size

__all__ = ["RunOptions", "run_options", "methods_taking", "stop_when_value", "SOLVER_OPTIONS", "simulate_parameters", "SOLVER_METHODS", "SWITCHING", "BRANCH_LIMIT",
           "MAX_STEPS", "INITIAL_TOLERANCE", "IMPLICIT_METHODS"]

# The methods simulate() accepts by name (solve_ivp's, and "ode.dop853", the compiled DOP853 of
# scipy.integrate.ode with events added by closedloop.simulation.dop853) come from
# closedloop.methods; an OdeSolver subclass is accepted too.
#: How switched forces are handled: with events and the sticking rule, or naively.
SWITCHING = ("events", "naive")
#: Default Kantorovich number above which a crossing of det Phi_z = 0 is refused (see the branch
#: guard in :mod:`closedloop.simulation.solve_ivp_runner`); simulate's ``branch_limit``.
BRANCH_LIMIT = 0.01
#: Constraint error above which an initial state is refused as inconsistent.
INITIAL_TOLERANCE = 1e-8
#: Default bound on the accepted steps of one simulate() call: a run that needs more fails clearly.
MAX_STEPS = 1_000_000
#: solve_ivp options that simulate() manages itself.
_RESERVED = ("events", "dense_output", "args", "vectorized")


@dataclass(frozen=True)
class RunOptions:
    """Everything simulate() was asked for, validated (see :func:`simulate` for the meaning)."""

    t_start: float
    t_end: float
    method: object                    # a name from SOLVER_METHODS, or an OdeSolver subclass
    rtol: object                      # float, or an array of them
    atol: object
    t_eval: np.ndarray | None
    multipliers: bool
    stop_when: object                 # callable or None
    sticking_resolution: float
    max_segments: int
    switching: str
    max_nfev: int | None
    max_steps: int
    work: bool
    branch_limit: float
    solver_options: types.MappingProxyType

    @property
    def method_name(self):
        return self.method if isinstance(self.method, str) else self.method.__name__

    @property
    def compiled(self):
        """True for the compiled DOP853 of scipy.integrate.ode."""
        return self.method == dop853.METHOD


#: The tightest relative tolerance float64 can deliver: 100 machine epsilons (scipy's solve_ivp
#: raises a smaller rtol to this with a warning; simulate refuses it, so that a run never claims
#: an accuracy it did not get).
RTOL_FLOOR = 100 * float(np.finfo(float).eps)


def _tolerance(name, value, floor=None):
    """A tolerance: a number, or an array of them, finite and > 0 (and >= ``floor``)."""
    if is_real(value):
        number = finite_number(name, value, minimum=0.0, strict=True)
        tolerances = np.array([number])
    else:
        tolerances = number = finite_array(name, value)
        if tolerances.size == 0 or np.any(tolerances <= 0):
            raise InputError(f"{name}: must be finite numbers > 0, got {shown_array(tolerances)}")
    if floor is not None and np.min(tolerances) < floor:
        raise InputError(f"{name}: must be >= {floor:.3g}, the tightest float64 can deliver (100 machine "
                         f"epsilons), got {np.min(tolerances):g}")
    return number


def _check_times(t_start, t_end, rtol, atol, sticking_resolution, branch_limit):
    """The checked ``(t_start, t_end, rtol, atol, sticking_resolution, branch_limit)``."""
    t_start = finite_number("t_start", t_start, unit="s")
    t_end = finite_number("t_end", t_end, unit="s")
    if not t_end > t_start:
        raise InputError(f"t_end: must be > t_start = {t_start:g} s, got {t_end:g}")
    if no_progress(t_end, t_start):
        raise InputError(f"t_end: the run must last at least {MIN_PROGRESS * max(1.0, abs(t_start)):g} s (a shorter "
                         f"one is a stall at a switch, see switching.MIN_PROGRESS), got t_end - t_start = "
                         f"{t_end - t_start:g} s")
    rtol, atol = _tolerance("rtol", rtol, RTOL_FLOOR), _tolerance("atol", atol)
    sticking_resolution = finite_number("sticking_resolution", sticking_resolution, minimum=0.0, strict=True,
                                        unit="s")
    if not (is_real(branch_limit) and branch_limit > 0):
        raise InputError(f"branch_limit: must be a number > 0 (math.inf turns the guard off), got "
                         f"{shown(branch_limit)}")
    return t_start, t_end, rtol, atol, sticking_resolution, _as_float(branch_limit)


def _as_float(value):
    """A number > 0 as a float: math.inf for an integer beyond float's range (10**400)."""
    try:
        return float(value)
    except OverflowError:
        return math.inf


def _tolerance_entries(name, tolerance, system, initial_state, formulation, method, work):
    """A tolerance array as solve_ivp takes it: one entry per entry of the integrator's state.

    An array of one entry is that number; Radau (rtol) and the compiled DOP853 take numbers only.
    """
    if not isinstance(tolerance, np.ndarray):
        return tolerance
    if tolerance.size == 1:
        return float(tolerance.reshape(-1)[0])
    if method == dop853.METHOD or (name == "rtol" and method == "Radau"):
        raise InputError(f"{name}: {method} takes one number, got {tolerance.size}")
    names = formulation.state_names(system) + ([WORK_NAME] if work else [])
    size = state_size(formulation.pack(system, initial_state.s, initial_state.sd).size, work)
    if tolerance.shape != (size,):
        raise InputError(f"{name}: need one value or {size}, one per entry of the {formulation.name} state "
                         f"({', '.join(names[:size])}), got "
                         f"{tolerance.size if tolerance.ndim == 1 else f'an array of shape {tolerance.shape}'}")
    return tolerance


def methods_taking(formulation, switching="events"):
    """The names of the methods that simulate() runs with ``formulation`` and ``switching``."""
    names = []
    for name in SOLVER_METHODS:
        try:
            formulation.check_method(name)
        except InputError:
            continue
        if name != dop853.METHOD or switching != "naive":
            names.append(name)
    return tuple(names)


def _is_ode_solver(method):
    """Whether the class ``method`` is a subclass of scipy.integrate.OdeSolver (imported only here, for a class)."""
    from scipy.integrate import OdeSolver

    return issubclass(method, OdeSolver) and method is not OdeSolver


def _check_method(system, formulation, method, switching, options):
    if not isinstance(formulation, Formulation):
        raise InputError(
            f"formulation: expected a Formulation (one of {', '.join(REGISTRY[name].__name__ for name in REGISTRY)}, "
            f"or a subclass of closedloop.Formulation), got {formulation!r}"
        )
    if not ((isinstance(method, str) and method in SOLVER_METHODS)
            or (isinstance(method, type) and _is_ode_solver(method))):
        choices = methods_taking(formulation, switching if switching in SWITCHING else "events")
        raise InputError(f"method: unknown {shown(method)}; choose one of {', '.join(choices)}")
    formulation.check_method(method)
    if method == dop853.METHOD and formulation.integrator(system, method) != method:     # rule 7 of the contract
        raise InputError(f"method: the {formulation.name} formulation alters the integrator's steps, which the "
                         f"compiled {dop853.METHOD} cannot do; choose one of "
                         f"{', '.join(m for m in methods_taking(formulation) if m != dop853.METHOD)}")
    if switching not in SWITCHING:
        raise InputError(f"switching: unknown {switching!r}; choose one of {', '.join(SWITCHING)}")
    if method == dop853.METHOD and switching == "naive":
        raise InputError(f"method: switching='naive' runs on solve_ivp; choose one of "
                         f"{', '.join(SOLVER_METHODS[:-1])}")
    reserved = set(_RESERVED) & set(options)
    if reserved:
        raise InputError(f"solver options: {sorted(reserved)} are managed by simulate()")
    _check_option_names(method, options)


#: The solver options each method takes through simulate()'s ``**options`` (solve_ivp's, and the compiled
#: DOP853's own); an OdeSolver subclass given as the method takes any.
SOLVER_OPTIONS = {
    **{name: ("first_step", "max_step") for name in ("RK45", "RK23", "DOP853")},
    **{name: ("first_step", "max_step", "jac", "jac_sparsity") for name in ("Radau", "BDF")},
    "LSODA": ("first_step", "max_step", "min_step", "jac", "lband", "uband"),
    dop853.METHOD: dop853.ALLOWED_OPTIONS,
}


def simulate_parameters():
    """The names of simulate()'s own keyword parameters, from its signature."""
    import inspect

    from . import simulate

    return tuple(name for name, parameter in inspect.signature(simulate).parameters.items()
                 if parameter.kind in (parameter.POSITIONAL_OR_KEYWORD, parameter.KEYWORD_ONLY))


def _check_option_names(method, options):
    """Refuse a keyword that is neither simulate()'s nor a solver option of ``method``, naming the close match.

    A misspelt option (``max_stp``) would reach solve_ivp, which warns and ignores it: the run would not be
    the one asked for.
    """
    if not isinstance(method, str):
        return                                   # an OdeSolver of one's own: its options are its own
    taken = SOLVER_OPTIONS[method]
    unknown = [name for name in options if name not in taken]
    if not unknown:
        return
    name = sorted(unknown)[0]
    own = simulate_parameters()
    if name in SOLVER_OPTIONS_OF_ANY:
        others = [other for other, names in SOLVER_OPTIONS.items() if name in names]
        first = f"{name}: not a solver option of {method} (only of {', '.join(others)});"
    else:
        guess = difflib.get_close_matches(name, own + taken, n=1)
        first = f"{name}: unknown keyword of simulate()" + (f"; did you mean {guess[0]!r}?" if guess else ";")
    raise InputError(f"{first} simulate() takes {', '.join(own)}, and for {method} the solver options "
                     f"{', '.join(taken)}")


#: Every solver option some method takes.
SOLVER_OPTIONS_OF_ANY = tuple(sorted({name for names in SOLVER_OPTIONS.values() for name in names}))


def _check_initial_state(system, initial_state):
    s0, sd0 = initial_state_arrays(initial_state, system.n)
    f0, Phi0 = system.constraints_and_jacobian(s0)
    scale = 1.0 + np.abs(s0).max()
    velocity = Phi0 @ sd0
    errors = (math.sqrt(f0 @ f0), math.sqrt(velocity @ velocity))       # the 2-norms, as np.linalg.norm
    if errors[0] > INITIAL_TOLERANCE * scale or errors[1] > INITIAL_TOLERANCE * (1.0 + np.abs(sd0).max()):
        raise InputError(
            f"initial_state: not consistent (|f| = {errors[0]:.3g}, |f'| = {errors[1]:.3g}, allowed "
            f"<= {INITIAL_TOLERANCE:g}); build it with consistent_initial_state"
        )
    _check_inertia(system, s0, sd0, Phi0)


#: Eigenvalues of M (and of N^T M N along the free motion) below this times the largest count as zero.
INERTIA_TOLERANCE = 1e-12


def _check_inertia(system, s0, sd0, Phi0):
    """Refuse a system whose kinetic energy T = s'^T M s' / 2 is not positive at the start.

    M of (5) may be singular in redundant coordinates (a massless coordinate the
    constraints carry), but it may not have a negative eigenvalue, and it must be
    positive definite along the free motion: N^T M N, with N a basis of the null
    space of Phi_s (18), is what every formulation inverts.
    """
    mass = np.asarray(system.dynamics(0.0, s0, sd0).mass_matrix, dtype=float)
    eigenvalues = np.linalg.eigvalsh(0.5 * (mass + mass.T))
    largest = float(np.max(np.abs(eigenvalues)))
    if largest == 0.0 or eigenvalues[0] < -INERTIA_TOLERANCE * largest:
        raise InputError(
            f"system: the mass matrix M of (5) at the initial state has the eigenvalues "
            f"{', '.join(f'{v:.3g}' for v in eigenvalues)}: the kinetic energy s'^T M s' / 2 is not positive; "
            "check the masses and moments of inertia among the parameter values"
        )
    free = null_space_basis(Phi0)
    reduced = np.linalg.eigvalsh(free.T @ mass @ free)
    if reduced[0] <= INERTIA_TOLERANCE * largest:
        raise InputError(
            f"system: the mechanism has no inertia along its free motion at the initial state (N^T M N of "
            f"(18) has the eigenvalue {reduced[0]:.3g}), so its accelerations are not determined; check the "
            "masses and moments of inertia among the parameter values"
        )


def stop_when_value(stop_when, t, s, sd):
    """``stop_when(t, s, sd)`` as a float, or an InputError that names the time where it is no finite number.

    A NaN never crosses zero, so a run would go on with stop_when silently off; a bool
    crosses zero at every False; an exception inside it would end the run with no time.
    """
    try:
        value = stop_when(t, s, sd)
    except Exception as error:
        raise InputError(f"stop_when: stop_when(t, s, sd) raised {type(error).__name__} at t = {t:.6g} s: "
                         f"{error}") from None
    number = value.item() if isinstance(value, np.ndarray) and value.size == 1 else value
    if isinstance(number, np.generic):
        number = number.item()
    if not is_real(number) or not math.isfinite(number):
        raise InputError(f"stop_when: must return a finite number (it stops the run where it crosses zero upward), "
                         f"got {shown(value)} at t = {t:.6g} s")
    return float(number)


def _check_steps(solver_options):
    """The step options: ``max_step`` (> 0, inf for none) and ``first_step`` (> 0) as floats [s], ``nsteps``."""
    checked = dict(solver_options)
    if "max_step" in checked:
        value = checked["max_step"]
        if not (is_real(value) and value > 0):
            raise InputError(f"max_step: must be a number > 0 s (math.inf: no bound), got {shown(value)}")
        checked["max_step"] = _as_float(value)
    if "first_step" in checked:
        checked["first_step"] = finite_number("first_step", checked["first_step"], minimum=0.0, strict=True,
                                              unit="s")
    if "nsteps" in checked:
        checked["nsteps"] = positive_integer("nsteps", checked["nsteps"])
    return checked


def run_options(system, initial_state, formulation, *, t_start, t_end, method, rtol, atol, t_eval, multipliers,
                stop_when, sticking_resolution, max_segments, switching, max_nfev, max_steps, work, branch_limit,
                solver_options):
    """Check every argument of :func:`simulate` (raising InputError) and return them as RunOptions."""
    instance_of("system", system, System)
    t_start, t_end, rtol, atol, sticking_resolution, branch_limit = _check_times(
        t_start, t_end, rtol, atol, sticking_resolution, branch_limit)
    multipliers, work = flag("multipliers", multipliers), flag("work", work)
    max_segments = positive_integer("max_segments", max_segments)
    _check_method(system, formulation, method, switching, solver_options)
    solver_options = _check_steps(solver_options)
    max_nfev = None if max_nfev is None else positive_integer("max_nfev", max_nfev)
    max_steps = positive_integer("max_steps", max_steps)
    _check_initial_state(system, initial_state)
    rtol, atol = (_tolerance_entries(name, value, system, initial_state, formulation, method, work)
                  for name, value in (("rtol", rtol), ("atol", atol)))
    t_eval = output_times(t_eval, t_start, t_end)
    if switching == "naive" and (stop_when is not None or work):
        name = "stop_when" if stop_when is not None else "work"
        raise InputError(f"{name}: a run with switching='naive' neither stops early nor integrates the work; "
                         "use switching='events'")
    if stop_when is not None:
        if not callable(stop_when):
            raise InputError(f"stop_when: expected a callable stop_when(t, s, sd) -> float, got {shown(stop_when)}")
        stop_when_value(stop_when, t_start, initial_state.s, initial_state.sd)     # refused here, not mid-run
    return RunOptions(t_start=t_start, t_end=t_end, method=method, rtol=rtol, atol=atol, t_eval=t_eval,
                      multipliers=bool(multipliers), stop_when=stop_when, sticking_resolution=sticking_resolution,
                      max_segments=max_segments, switching=switching, max_nfev=max_nfev, max_steps=max_steps,
                      work=bool(work), branch_limit=branch_limit,
                      solver_options=types.MappingProxyType(dict(solver_options)))
