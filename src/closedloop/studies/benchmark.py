"""Error against run time: which formulation and integrator buy the most accuracy per second.

The study behind ``closedloop benchmark`` and chapter 8.  For each of the paper's four
cases it integrates the slider-crank over 0-20 s with every entry of :func:`study_entries`
(the library's formulations, and the same model written the usual way with
``sympy.physics.mechanics``, :mod:`closedloop.studies.baseline`, lambdified with each of
its two printers, numpy and math), every method of the settings and a ladder of tolerances
(``atol = rtol``), and records one row per run (:func:`run_study` names its fields).  Every
comparison with the library (:func:`best_row` with ``library=False``,
:func:`cheapest_choices`, :func:`performance_ratios`) takes the cheapest row of either
printer: the library is measured against the baseline at its best.

The reference is the minimal-coordinate solution (:class:`~closedloop.formulations.Minimal`,
DOP853, rtol = atol = 1e-13); its own accuracy is estimated by its distance to the
rtol = atol = 1e-12 solution, recorded per case.

Pruning: along each curve (one case, one entry, one method) the tolerances are taken from
loose to tight, and the curve stops after a run whose median CPU time exceeds
``time_cap_s``, or when error_t10 has not fallen below half of the curve's best error while
staying above ``PLATEAU_RATIO`` times rtol for ``plateau`` tolerances in a row (the error
has reached its floor).  A failed run does not stop the curve; a row's ``curve_end`` says
why its curve stopped.  Every entry runs all of its methods in the main case (case 2); the
other cases run ``other_case_methods`` only (the baseline's entries ``baseline_methods``),
which keeps the default study under ten minutes on two cores.
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass

import numpy as np

from ..errors import ClosedLoopError, InputError
from .. import methods as method_names
from ..formulations import Augmented, Baumgarte, ClosedForm, Minimal, Orthogonal, Projected, baumgarte_from_step
from ..methods import SOLVER_METHODS
from ..simulation import simulate
from ..simulation.options import methods_taking
from ..slider_crank import get_case, initial_state, slider_crank_system
from .baseline import LagrangesBaseline
from .provenance import provenance, read_with_provenance, source_fingerprint

__all__ = [
    "Entry", "study_entries", "StudySettings", "DEFAULT_SETTINGS", "QUICK_SETTINGS", "run_study",
    "cheapest_choices", "performance_ratios", "best_row", "source_fingerprint", "residual_traces",
    "format_table", "load_study", "BASELINE_KEY", "BASELINE_MATH_KEY", "BASELINE_KEYS", "is_baseline",
]

T_END = 20.0                   # s, the length of every run
T_CHECK = 10.0                 # s, where error_t10 is measured
GRID_POINTS = 2001             # the common output grid 0, 0.01, ..., 20 s
REFERENCE_METHOD = "DOP853"
REFERENCE_TOL = 1e-13
REFERENCE_CHECK_TOL = 1e-12
ACCURACY_LEVELS = (1e-2, 1e-4, 1e-6, 1e-8, 1e-10)
PERFORMANCE_TARGET = 1e-8      # error_t10 at which the library is compared with the baseline
PLATEAU_RATIO = 100.0          # an error this many times rtol no longer follows the tolerance
STEP_RULE_DT = 0.05            # s: Delta t of the rule alpha = 1/dt, beta = sqrt(2)/dt (chapter 3 uses 0.1-0.02)
#: The key of the baseline lambdified with sympy's default printer, for numpy.
BASELINE_KEY = "sympy"
#: The key of the same baseline lambdified for Python's math module.
BASELINE_MATH_KEY = "sympy-math"
#: The baseline's entries, one per printer: the usual way at its best is the cheaper of the two.
BASELINE_KEYS = (BASELINE_KEY, BASELINE_MATH_KEY)
#: solve_ivp's methods but RK23 (RK45 is the same kind of method, of higher order).
SOLVE_IVP_METHODS = tuple(method for method in method_names.SOLVE_IVP_METHODS if method != "RK23")
#: solve_ivp's five, and the compiled DOP853 of scipy.integrate.ode (closedloop.simulation.dop853).
ALL_METHODS = SOLVE_IVP_METHODS + (method_names.COMPILED_METHOD,)
#: The methods of SOLVE_IVP_METHODS that the projected formulation takes (it says which, methods_taking asks it).
EXPLICIT_RK = tuple(method for method in methods_taking(Projected()) if method in SOLVE_IVP_METHODS)


@dataclass(frozen=True)
class Entry:
    """One contestant of the study.

    Attributes
    ----------
    key : str
        Stable short name, the ``formulation`` field of a row.
    label : str
        Display name in tables and figures.
    formulation : object or None
        A closedloop formulation for :func:`closedloop.simulate`; None for the
        sympy.physics.mechanics baseline.
    methods : tuple of str
        The methods it runs, when the settings select them (default: solve_ivp's
        five of :data:`SOLVE_IVP_METHODS`; the closed form also runs ode.dop853).
    modules : str
        The baseline's printer, ``lambdify(..., modules=...)``: "numpy" or "math"
        (see :class:`~closedloop.studies.baseline.LagrangesBaseline`); unused by a formulation.
    """

    key: str
    label: str
    formulation: object
    methods: tuple = SOLVE_IVP_METHODS
    modules: str = "numpy"


def _entry(formulation, label, suffix="", methods=SOLVE_IVP_METHODS):
    """The Entry of ``formulation``, keyed by its registry name and ``suffix`` ("-5-5" for a second pair of gains)."""
    return Entry(formulation.name + suffix, label, formulation, methods)


def study_entries():
    """The contestants, in display order: a new formulation is one more line here."""
    return (
        _entry(Augmented(), "Augmented (12)"),
        _entry(Baumgarte(5, 5), "Baumgarte (5, 5)", "-5-5"),
        _entry(Baumgarte(10, 10), "Baumgarte (10, 10)", "-10-10"),
        _entry(baumgarte_from_step(STEP_RULE_DT), f"Baumgarte 1/dt, dt = {STEP_RULE_DT:g} s", "-step"),
        _entry(Orthogonal(5, 5), "Orthogonal (26), (5, 5)"),
        _entry(Minimal(), "Minimal"),
        _entry(Projected(), "Projected", methods=EXPLICIT_RK),
        _entry(ClosedForm(1, 1), "Closed form (26), (1, 1)", methods=("DOP853", "ode.dop853")),
        Entry(BASELINE_KEY, "sympy.physics.mechanics, numpy printer", None),
        Entry(BASELINE_MATH_KEY, "sympy.physics.mechanics, math printer", None, modules="math"),
    )


def is_baseline(key):
    """Whether ``key`` (a row's ``formulation``) names one of the baseline's entries."""
    return key in BASELINE_KEYS


@dataclass(frozen=True)
class StudySettings:
    """What one study runs; recorded in the data file.

    Attributes
    ----------
    quick : bool
    cases : tuple of int
    methods : tuple of str
        The methods of the main case.
    main_case : int
    other_case_methods : tuple of str
        The methods of the other cases.
    baseline_methods : tuple of str
        The baseline's methods in the other cases (both printers).
    rtols : tuple of float
        From loose to tight; ``atol = rtol``.
    repeats : int
        Timed runs per row; cpu_s is their median.
    time_cap_s : float
        A curve stops after a row whose cpu_s exceeds this.
    plateau : int
        A curve stops after this many rows in a row without halving its best error.
    """

    quick: bool = False
    cases: tuple = (1, 2, 3, 4)
    methods: tuple = ALL_METHODS
    main_case: int = 2
    other_case_methods: tuple = ("DOP853", "ode.dop853")
    baseline_methods: tuple = ("DOP853", "LSODA")
    rtols: tuple = tuple(10.0 ** -k for k in range(3, 13))
    repeats: int = 5
    time_cap_s: float = 0.25
    plateau: int = 2
    t_end: float = T_END
    t_check: float = T_CHECK
    grid_points: int = GRID_POINTS
    reference: str = f"minimal, {REFERENCE_METHOD}, rtol = atol = {REFERENCE_TOL:g}"

    def methods_of(self, case, key=None):
        """The methods run in ``case`` (by the entry called ``key``)."""
        if case == self.main_case:
            return self.methods
        return self.baseline_methods if is_baseline(key) else self.other_case_methods

    def as_dict(self):
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in asdict(self).items()}


#: The full study, as the book's data file records it.
DEFAULT_SETTINGS = StudySettings()
#: The quick study: case 2 only, DOP853 and ode.dop853, three tolerances, one repeat (well under a minute).
QUICK_SETTINGS = StudySettings(quick=True, cases=(2,), methods=("DOP853", "ode.dop853"), other_case_methods=(),
                               rtols=(1e-3, 1e-6, 1e-9), repeats=1, time_cap_s=0.5)


# -- running ---------------------------------------------------------------------------------
@dataclass
class _Context:
    """What every run of one case shares."""

    system: object
    baselines: dict                 # printer -> LagrangesBaseline, for the baseline's entries
    state: object
    grid: np.ndarray                # the output grid over [0, t_end]: the runs end at its last time
    check_index: int                # where t_check, where error_t10 is measured, is in the grid
    reference: np.ndarray           # 6 x grid.size


def _run(entry, context, method, rtol, t_eval, residuals=False):
    """One run: ``(t, y (6 x N), nfev)``, and ``(|f|, |f'|)`` at the output times if asked."""
    if entry.formulation is None:
        baseline = context.baselines[entry.modules]
        res = baseline.simulate(context.state, float(context.grid[-1]), method, rtol, rtol, t_eval=t_eval)
        y = np.vstack((res.s, res.sd))
        norms = _residuals(context.system, y) if residuals else None
    else:
        res = simulate(context.system, context.state, float(context.grid[-1]), formulation=entry.formulation,
                       method=method, rtol=rtol, atol=rtol, t_eval=t_eval)
        y = np.vstack((res.s, res.sd))
        norms = (res.constraint_error, res.velocity_constraint_error)     # simulate computed them
    return (res.t, y, res.nfev, norms) if residuals else (res.t, y, res.nfev)


def _residuals(system, y):
    """``(|f|, |f'|)`` of (32) and (9) at every column of y (6 x N)."""
    f_norm, fd_norm = np.empty(y.shape[1]), np.empty(y.shape[1])
    for k in range(y.shape[1]):
        f, Phi = system.constraints_and_jacobian(y[:3, k])
        f_norm[k], fd_norm[k] = np.linalg.norm(f), np.linalg.norm(Phi @ y[3:, k])
    return f_norm, fd_norm


def _measure(entry, context, case, method, rtol, repeats):
    """One row of the study."""
    row = {"case": case, "formulation": entry.key, "label": entry.label, "method": method, "rtol": rtol,
           "atol": rtol, "repeats": repeats}
    try:
        t, y, _, (f_norm, fd_norm) = _run(entry, context, method, rtol, context.grid, residuals=True)
        if t.size != context.grid.size:
            raise ClosedLoopError(f"the run stopped at t = {t[-1]:.6g} s")
        cpu, t_check = [], float(context.grid[context.check_index])
        for _ in range(max(1, repeats)):
            start = time.process_time()
            t_timed, y_timed, nfev = _run(entry, context, method, rtol, (t_check, context.grid[-1]))
            cpu.append(time.process_time() - start)
        if t_timed.size != 2 or t_timed[0] != t_check:
            raise ClosedLoopError(f"the timed run stopped at t = {t_timed[-1]:.6g} s")
    except ClosedLoopError as error:
        row.update(status=f"failed: {error}", cpu_s=None, cpu_repeats_s=[], nfev=None, error_t10=None,
                   max_state_error=None, max_constraint_error=None, max_velocity_constraint_error=None)
        return row
    difference = np.abs(y - context.reference)
    error_t10 = float(np.abs(y_timed[:, 0] - context.reference[:, context.check_index]).max())
    import statistics                       # here: the command line builds its parser from this module

    row.update(status="ok", cpu_s=statistics.median(cpu), cpu_repeats_s=cpu, nfev=int(nfev),
               error_t10=error_t10, max_state_error=max(float(difference.max()), error_t10),
               max_constraint_error=float(f_norm.max()), max_velocity_constraint_error=float(fd_norm.max()))
    return row


def _curve(entry, context, case, method, settings):
    """The rows of one curve, loose to tight, with the pruning rules of the module docstring."""
    rows, best, flat = [], math.inf, 0
    for rtol in settings.rtols:
        row = _measure(entry, context, case, method, rtol, settings.repeats)
        rows.append(row)
        if row["status"] != "ok":
            continue
        # flat: the error neither halved nor still follows the tolerance (it sits far above rtol);
        # errors near rtol may wander up and down between tolerances without being at a floor
        stuck = row["error_t10"] >= 0.5 * best and row["error_t10"] >= PLATEAU_RATIO * rtol
        flat = flat + 1 if stuck else 0
        best = min(best, row["error_t10"])
        if row["cpu_s"] > settings.time_cap_s:
            row["curve_end"] = f"time cap: cpu_s > {settings.time_cap_s:g} s"
            break
        if flat >= settings.plateau:
            row["curve_end"] = f"error plateau: not halved for {settings.plateau} tolerances"
            break
    else:
        rows[-1]["curve_end"] = "tightest rtol"
    return rows


def _grid(settings):
    """``(grid, check_index)``: ``grid_points`` even times over ``[0, t_end]``, with ``t_check`` added unless
    it is one of them (the errors at t_check are measured there, not at the nearest grid time)."""
    grid = np.union1d(np.linspace(0.0, settings.t_end, settings.grid_points), [settings.t_check])
    return grid, int(np.searchsorted(grid, settings.t_check))


def _reference(system, state, grid, check_index):
    """The reference on the grid (which ends at t_end) and its agreement with the rtol = 1e-12 solution."""
    runs = {}
    for tol in (REFERENCE_TOL, REFERENCE_CHECK_TOL):
        res = simulate(system, state, float(grid[-1]), formulation=Minimal(), method=REFERENCE_METHOD, rtol=tol,
                       atol=tol, t_eval=grid)
        runs[tol] = (np.vstack((res.s, res.sd)), res.cpu_time)
    difference = np.abs(runs[REFERENCE_TOL][0] - runs[REFERENCE_CHECK_TOL][0])
    check = {"agreement_t10": float(difference[:, check_index].max()),
             "agreement_max": float(difference.max()), "cpu_s": runs[REFERENCE_TOL][1]}
    return runs[REFERENCE_TOL][0], check


def _baselines(system, entries):
    """``printer -> LagrangesBaseline`` for the printers of the baseline's entries among ``entries``."""
    printers = dict.fromkeys(entry.modules for entry in entries if entry.formulation is None)
    return {printer: LagrangesBaseline(system.parameters, system.reading, modules=printer) for printer in printers}


def run_study(settings=DEFAULT_SETTINGS, entries=None, progress=None):
    """Run the study; returns the JSON-ready dict (provenance, references, rows).

    Parameters
    ----------
    settings : StudySettings
    entries : sequence of Entry, optional
        Default :func:`study_entries`.
    progress : callable, optional
        ``progress(text)`` after each curve (the CLI prints it to stderr).

    Returns
    -------
    dict
        ``closedloop_version``, ``source_fingerprint``, ``settings``, ``machine``,
        ``baseline_derivation_cpu_s`` (per printer), ``references`` (per case: the reference's
        agreement with the rtol = 1e-12 solution), ``wall_s`` and ``rows``, one dict per run
        with its case, entry, method, rtol, ``status`` and ``curve_end``, and

        - ``error_t10``: ``max_k |y_k(10) - y_k,ref(10)|`` of ``y = [phi, psi, x_C, phi', psi',
          x_C']`` at t = 10 s, from the timed run itself, so that the error and the CPU time
          belong to the same steps;
        - ``max_state_error``: the same max-norm over the 2001 points ``t = 0, 0.01, ..., 20`` s
          of an untimed run with that grid as ``t_eval`` (the same steps: the grid is
          interpolated from each method's dense output);
        - ``max_constraint_error``, ``max_velocity_constraint_error``: ``max |f|`` of (32) and
          ``max |Phi_s s'|`` over that grid;
        - ``nfev``: right-hand-side evaluations of the timed run;
        - ``cpu_s``: the median over ``repeats`` runs of the process time of a 20 s run that
          outputs the state at 10 s and 20 s only (the same output work for every entry).
    """
    for method in settings.methods + settings.other_case_methods + settings.baseline_methods:
        if method not in SOLVER_METHODS:
            raise InputError(f"methods: unknown {method!r}; choose from {', '.join(SOLVER_METHODS)}")
    for case in settings.cases:
        get_case(case)
    if not 0.0 < settings.t_check < settings.t_end:
        raise InputError(f"t_check: must lie in (0, t_end = {settings.t_end:g}) s, got {settings.t_check!r}")
    wall = time.perf_counter()
    entries = study_entries() if entries is None else tuple(entries)
    system = slider_crank_system()
    baselines = _baselines(system, entries)
    grid, check_index = _grid(settings)
    data = provenance(settings)
    data.update(baseline_derivation_cpu_s={printer: baseline.derivation_cpu_time
                                           for printer, baseline in baselines.items()},
                references={}, rows=[])
    for case in settings.cases:
        number = get_case(case)
        state = initial_state(system, number.phi0, number.dphi0)
        reference, check = _reference(system, state, grid, check_index)
        data["references"][str(case)] = check
        context = _Context(system, baselines, state, grid, check_index, reference)
        for entry in entries:
            for method in (m for m in settings.methods_of(case, entry.key) if m in entry.methods):
                rows = _curve(entry, context, case, method, settings)
                data["rows"].extend(rows)
                if progress is not None:
                    progress(f"case {case}: {entry.label}, {method}: {len(rows)} rows, "
                             f"{rows[-1].get('curve_end')}")
    data["wall_s"] = time.perf_counter() - wall
    return data


# -- reading the rows ------------------------------------------------------------------------
def load_study(path):
    """A study written by ``closedloop benchmark --json FILE``, checked for its parts.

    Returns the dict of :func:`run_study`, with one more key, ``"current"``: True
    when its ``source_fingerprint`` is that of the library now imported.
    """
    return read_with_provenance(path, ("references", "rows"), "a study", "benchmark")


def best_row(rows, level, library=None):
    """The row with the lowest cpu_s among those with error_t10 <= level, or None.

    ``library=True`` keeps only the library's rows, ``False`` only the baseline's (both printers).
    """
    met = [r for r in rows if r["status"] == "ok" and r["error_t10"] <= level
           and (library is None or (not is_baseline(r["formulation"])) == library)]
    return min(met, key=lambda r: r["cpu_s"]) if met else None


def cheapest_choices(rows, levels=ACCURACY_LEVELS):
    """Per case and accuracy level: the cheapest row overall and the baseline's cheapest (either printer).

    Returns a list of dicts ``case, level, best (row or None), baseline (row or None)``.
    """
    table = []
    for case in sorted({r["case"] for r in rows}):
        of_case = [r for r in rows if r["case"] == case]
        for level in levels:
            table.append({"case": case, "level": level, "best": best_row(of_case, level),
                          "baseline": best_row(of_case, level, library=False)})
    return table


def performance_ratios(rows, target=PERFORMANCE_TARGET):
    """Per case: baseline cpu_s / library cpu_s, each the cheapest row with error_t10 <= target.

    The baseline's row is the cheapest of both printers: the usual way at its best printer, method
    and tolerance.  Returns a dict ``case -> {"library": row, "baseline": row, "ratio": float or None}``;
    ratio > 1 means the library's best is faster.
    """
    ratios = {}
    for case in sorted({r["case"] for r in rows}):
        of_case = [r for r in rows if r["case"] == case]
        lib, base = best_row(of_case, target, library=True), best_row(of_case, target, library=False)
        ratio = base["cpu_s"] / lib["cpu_s"] if lib is not None and base is not None else None
        ratios[case] = {"library": lib, "baseline": base, "ratio": ratio}
    return ratios


def _describe(row):
    return "-" if row is None else f"{row['label']}, {row['method']}, rtol {row['rtol']:.0e}"


def format_table(data):
    """The text the CLI prints: references, the cheapest choices, the performance ratio."""
    lines = [f"closedloop {data['closedloop_version']} benchmark "
             f"({'quick' if data['settings']['quick'] else 'default'} settings), "
             f"{len(data['rows'])} rows, wall time {data['wall_s']:.0f} s",
             f"reference: {data['settings']['reference']}; agreement with rtol = 1e-12 at t = 10 s:"]
    lines += [f"  case {case}: {check['agreement_t10']:.1e} (max over 0-20 s: {check['agreement_max']:.1e})"
              for case, check in data["references"].items()]
    lines += ["", "Cheapest choice per accuracy level (error at t = 10 s <= level; CPU = median process time)"]
    header = f"{'case':>4}  {'level':>7}  {'cheapest':<52}  {'CPU [s]':>8}  {'baseline CPU':>12}  {'ratio':>6}"
    lines += [header, "-" * len(header)]
    for item in cheapest_choices(data["rows"]):
        best, base = item["best"], item["baseline"]
        cpu = f"{best['cpu_s']:.4f}" if best else "-"
        base_cpu = f"{base['cpu_s']:.4f}" if base else "-"
        ratio = f"{base['cpu_s'] / best['cpu_s']:.2f}" if best and base else "-"
        lines.append(f"{item['case']:>4}  {item['level']:>7.0e}  {_describe(best):<52}  {cpu:>8}  "
                     f"{base_cpu:>12}  {ratio:>6}")
    lines += ["", f"Performance at error_t10 <= {PERFORMANCE_TARGET:.0e}: baseline CPU / best library CPU "
                  "(> 1: the library is faster; the baseline at its best printer, method and rtol)"]
    for case, item in performance_ratios(data["rows"]).items():
        ratio = "-" if item["ratio"] is None else f"{item['ratio']:.2f}"
        lines.append(f"  case {case}: {ratio}   library: {_describe(item['library'])};  "
                     f"baseline: {_describe(item['baseline'])}")
    return "\n".join(lines)


# -- residual traces (the data of the residual figure) ------------------------------------
def residual_traces(case=2, method="DOP853", rtol=1e-6, keys=None):
    """|f| and |f'| against time on the common grid for the main formulations, one method and rtol.

    ``keys`` are entries' keys; default Augmented, Baumgarte (5, 5), Orthogonal, Minimal, Projected
    and the baseline's.  Returns a dict ``label -> (t, |f|, |f'|)``.
    """
    if keys is None:
        keys = (Augmented.name, Baumgarte.name + "-5-5", Orthogonal.name, Minimal.name, Projected.name, BASELINE_KEY)
    system = slider_crank_system()
    number = get_case(case)
    state = initial_state(system, number.phi0, number.dphi0)
    grid, _ = _grid(DEFAULT_SETTINGS)
    entries = {e.key: e for e in study_entries()}
    unknown = [k for k in keys if k not in entries]
    if unknown:
        raise InputError(f"keys: unknown {unknown}; choose from {', '.join(entries)}")
    context = _Context(system, _baselines(system, [entries[key] for key in keys]), state, grid, 0, None)
    traces = {}
    for key in keys:
        t, _, _, norms = _run(entries[key], context, method, rtol, grid, residuals=True)
        traces[entries[key].label] = (t, *norms)
    return traces
