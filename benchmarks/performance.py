"""Performance of closedloop's formulations against a plain sympy.physics.mechanics model.

Run as ``python benchmarks/performance.py [--quick]``.  Every figure printed
comes from the same run of this script; nothing is read from earlier runs.
This is a benchmark script, not a test: it asserts nothing.

The problem
-----------
The slider-crank of Khang, Quyen and Mai Anh (2018) in the vertical plane,
case 2 of the paper (phi0 = pi/2, phi0' = 1 rad/s), Table 1 data, drive torque
41.45 + 0.01 sin(2 pi t) N m on phi and the gas force ``+F_gas(x, x')`` on x
(:func:`closedloop.slider_crank.gas_force`), integrated over 20 s from the
same consistent initial state.

What is measured
----------------
CPU time
    ``time.process_time()`` around one ``simulate(...)`` call for the library
    (so it includes the library's own event handling and output processing),
    and around one ``solve_ivp(...)`` call for the baseline.  The median of
    ``--repeats`` runs (3 by default, 1 with ``--quick``).  Each timed run is
    a full 20 s run with the solver's own output steps (``t_eval=None``).
nfev
    Right-hand-side evaluations of that 20 s run (summed over the library's
    segments between switches; for LSODA it includes the finite-difference
    Jacobian evaluations).
err@10s
    ``max |[s, s'] - [s, s']_ref|`` at t = 10 s.  The reference is the Minimal
    formulation with DOP853 at rtol = atol = 1e-12.  The state at 10 s comes
    from a second, untimed run that ends at t = 10 s (its last output point),
    for the library and the baseline alike, so that the timed run is exactly
    the 20 s run with the solver's own output steps.
max|f|
    The largest constraint error ``|f(s)|`` over the output points of the 20 s
    run: for the library its ``max_constraint_error``, for the baseline the
    same norm evaluated afterwards (outside the timing) at the solver's steps.

Equal accuracy
    For each formulation and each method, the loosest rtol in the tolerance
    list (atol = rtol) whose err@10s is <= 1e-8, and the CPU time of a 20 s
    run at that tolerance.  The best method of each formulation is the one
    with the lowest such CPU time.  ``speed-up = baseline CPU / library CPU``,
    both at equal accuracy and each with its own best method: > 1 means the
    library is faster.

The baseline ("the usual way")
------------------------------
``sympy.physics.mechanics``: ``dynamicsymbols`` for phi, psi, x; L = T - Pi
typed in from the paper; ``LagrangesMethod(L, [phi, psi, x],
hol_coneqs=[f1, f2], forcelist=..., frame=N)``.  Forces are applied the way the
mechanics tutorials do it: the drive torque as ``(A, torque(t)*N.z)`` on the
crank frame A (rotated by phi about N.z), the gas force as ``(P, F*N.x)`` on the
slider point P = O + x N.x, with F a plain symbol that the right-hand side
fills in with ``gas_force(x, x')`` at every call (no events: the typical user
does not stop at the switches; F happens to be continuous across them for this
stroke, only its slope jumps).  Table 1 values are substituted before
``lambdify`` (default settings, numpy), and the right-hand side solves
``mass_matrix_full @ [s', s'', lambda] = forcing_full`` with ``np.linalg.solve``.
This is the unstabilised augmented (index-1) system, like ``Augmented()``.

Derivation times are CPU times of the symbolic work: for the baseline from the
first symbol to the lambdified functions; for the library the first
``slider_crank_system()`` call of this process (``closedloop.derive`` is cached
per process, so it is only measured when nothing derived it before).

How to read it
--------------
Table 1 compares the methods at one tolerance; err@10s there shows how far
that tolerance is from the reference.  Table 2 is the fair comparison: each
contestant at the loosest tolerance that meets the same error target.  A run
that cannot meet the target within the tolerance list is shown as "-".
"""

from __future__ import annotations

import argparse
import math
import statistics
import sys
import time
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

T_END = 20.0                 # s, the timed runs
T_CHECK = 10.0               # s, where the error is measured
ERROR_TARGET = 1e-8          # the "equal accuracy" target of err@10s
REFERENCE_TOL = 1e-12
TABLE1_TOL = 1e-9
METHODS = ("RK45", "DOP853", "LSODA")
FULL_TOLERANCES = tuple(10.0 ** -k for k in range(6, 13))    # 1e-6 ... 1e-12
QUICK_TOLERANCES = tuple(10.0 ** -k for k in range(8, 13))   # 1e-8 ... 1e-12
BASELINE_BUDGET = 300.0      # s of CPU for one untimed baseline accuracy run


@dataclass(frozen=True)
class Figures:
    """What one contestant achieved at one method and tolerance."""

    cpu: float               # s, median over the repeats of the 20 s run
    nfev: int
    error: float             # err@10s
    constraint: float        # max |f| over the 20 s run
    rtol: float
    method: str


class BudgetExceeded(RuntimeError):
    """An untimed baseline run used more CPU time than allowed."""


# -- the library ------------------------------------------------------------------------------
def library_system():
    """``(system, derivation CPU seconds or None)``; None if something derived it earlier."""
    from closedloop.model import derive
    from closedloop.slider_crank import slider_crank_system

    fresh = derive.cache_info().currsize == 0
    start = time.process_time()
    system = slider_crank_system()
    elapsed = time.process_time() - start
    return system, (elapsed if fresh else None)


def library_formulations():
    """``(label, formulation)`` pairs compared in the tables."""
    from closedloop import Augmented, Baumgarte, Minimal, Orthogonal

    return (("Augmented", Augmented()), ("Baumgarte(5,5)", Baumgarte(5, 5)),
            ("Baumgarte(10,10)", Baumgarte(10, 10)), ("Orthogonal(5,5)", Orthogonal(5, 5)),
            ("Minimal", Minimal()))


def library_runner(system, ic, formulation):
    """``run(method, tol, t_end) -> (cpu, nfev, state at t_end, max|f|)`` for one formulation."""
    from closedloop import simulate

    def run(method, tol, t_end):
        start = time.process_time()
        res = simulate(system, ic, t_end, formulation=formulation, method=method, rtol=tol, atol=tol)
        cpu = time.process_time() - start
        state = np.concatenate((res.s[:, -1], res.sd[:, -1]))
        return cpu, res.nfev, state, res.max_constraint_error

    return run


# -- the baseline: sympy.physics.mechanics, written the usual way ------------------------------
def derive_baseline(parameters):
    """Lagrange's equations by ``LagrangesMethod``; returns ``(mass_full, forcing_full, CPU s)``.

    Both are lambdified with default settings as functions of
    ``(phi, psi, x, phi', psi', x', t, F)`` with Table 1 values substituted.
    """
    import sympy as sm
    import sympy.physics.mechanics as me

    start = time.process_time()
    phi, psi, x = me.dynamicsymbols("phi psi x")
    dphi, dpsi, dx = me.dynamicsymbols("phi psi x", 1)
    t = me.dynamicsymbols._t
    l1, a1, m1, I1, l2, a2, m2, I2, m3, g = sm.symbols("l1 a1 m1 I1 l2 a2 m2 I2 m3 g")
    F = sm.Symbol("F")                                   # gas force, filled in numerically

    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", (phi, N.z))             # the crank: torque acts here
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x)                        # the slider: gas force acts here

    T = (sm.Rational(1, 2) * (I1 + m1 * a1**2 + m2 * l1**2) * dphi**2
         + sm.Rational(1, 2) * (I2 + m2 * a2**2) * dpsi**2 + sm.Rational(1, 2) * m3 * dx**2
         - m2 * l1 * a2 * dphi * dpsi * sm.cos(phi - psi))
    Pi = m1 * g * a1 * sm.sin(phi) + m2 * g * l1 * sm.sin(phi) - m2 * g * a2 * sm.sin(psi)
    f1 = l1 * sm.cos(phi) - l2 * sm.cos(psi) - x
    f2 = l1 * sm.sin(phi) - l2 * sm.sin(psi)
    torque = 41.45 + 0.01 * sm.sin(2 * sm.pi * t)

    method = me.LagrangesMethod(T - Pi, [phi, psi, x], hol_coneqs=[f1, f2],
                                forcelist=[(A, torque * N.z), (P, F * N.x)], frame=N)
    method.form_lagranges_equations()
    values = {sm.Symbol(name): value for name, value in parameters.as_dict().items()}
    args = [phi, psi, x, dphi, dpsi, dx, t, F]
    mass_full = sm.lambdify(args, method.mass_matrix_full.subs(values))
    forcing_full = sm.lambdify(args, method.forcing_full.subs(values))
    return mass_full, forcing_full, time.process_time() - start


def baseline_rhs(mass_full, forcing_full, deadline=None):
    """The right-hand side ``y' = F(t, y)``, ``y = [phi, psi, x, phi', psi', x']``.

    With ``deadline`` (a process_time value) it raises BudgetExceeded past it;
    only the untimed accuracy runs use that.
    """
    from closedloop.slider_crank import gas_force

    def rhs(t, y):
        force = gas_force(y[2], y[5])
        sol = np.linalg.solve(mass_full(*y, t, force), forcing_full(*y, t, force))
        return sol[:6, 0]

    if deadline is None:
        return rhs

    def guarded(t, y):
        if time.process_time() > deadline:
            raise BudgetExceeded
        return rhs(t, y)

    return guarded


def constraint_norms(parameters, s):
    """|f(s)| of the two loop constraints at each column of s (3 x N)."""
    p = parameters
    f1 = p.l1 * np.cos(s[0]) - p.l2 * np.cos(s[1]) - s[2]
    f2 = p.l1 * np.sin(s[0]) - p.l2 * np.sin(s[1])
    return np.hypot(f1, f2)


def baseline_runner(parameters, ic, mass_full, forcing_full):
    """``run(method, tol, t_end) -> (cpu, nfev, state at t_end, max|f|)`` for the baseline.

    Runs that end at T_CHECK (the accuracy runs) are limited to BASELINE_BUDGET
    seconds of CPU and raise BudgetExceeded beyond.
    """
    y0 = np.concatenate((ic.s, ic.sd))

    def run(method, tol, t_end):
        deadline = time.process_time() + BASELINE_BUDGET if t_end < T_END else None
        rhs = baseline_rhs(mass_full, forcing_full, deadline)
        start = time.process_time()
        sol = solve_ivp(rhs, (0.0, t_end), y0, method=method, rtol=tol, atol=tol)
        cpu = time.process_time() - start
        if sol.status != 0:
            raise RuntimeError(f"baseline {method} at rtol {tol:g}: {sol.message}")
        return cpu, sol.nfev, sol.y[:, -1], float(np.max(constraint_norms(parameters, sol.y[:3])))

    return run


# -- measuring ---------------------------------------------------------------------------------
def error_at_check(run, method, tol, reference):
    """err@10s of one contestant: inf if it ran out of budget, nan if the integration failed."""
    from closedloop import ClosedLoopError

    try:
        state = run(method, tol, T_CHECK)[2]
    except BudgetExceeded:
        return math.inf
    except (ClosedLoopError, RuntimeError) as exc:
        print(f"  note: {method} at rtol {tol:.0e} failed ({exc}); counted as not meeting the target")
        return math.nan
    return float(np.max(np.abs(state - reference)))


def measure(run, method, tol, reference, repeats, error=None):
    """Figures of one contestant at one method and tolerance (timed over ``repeats`` runs)."""
    outcomes = [run(method, tol, T_END) for _ in range(repeats)]
    cpu = statistics.median(o[0] for o in outcomes)
    error = error_at_check(run, method, tol, reference) if error is None else error
    return Figures(cpu, outcomes[-1][1], error, outcomes[-1][3], tol, method)


def equal_accuracy(run, method, tolerances, reference, repeats):
    """Figures at the loosest tolerance with err@10s <= ERROR_TARGET, or None (and the capped flag)."""
    capped = False
    for tol in tolerances:
        error = error_at_check(run, method, tol, reference)
        capped = capped or math.isinf(error)
        if error <= ERROR_TARGET:
            return measure(run, method, tol, reference, repeats, error), capped
    return None, capped


# -- printing ----------------------------------------------------------------------------------
def table(headers, rows):
    """A fixed-width text table; numbers are already formatted as strings."""
    widths = [max(len(h), *(len(r[i]) for r in rows)) for i, h in enumerate(headers)]
    line = "  ".join("-" * w for w in widths)
    out = ["  ".join(h.rjust(w) if i else h.ljust(w) for i, (h, w) in enumerate(zip(headers, widths))), line]
    for r in rows:
        out.append("  ".join(c.rjust(w) if i else c.ljust(w) for i, (c, w) in enumerate(zip(r, widths))))
    return "\n".join(out)


def figure_cells(fig):
    return [fig.method, f"{fig.rtol:.0e}", f"{fig.cpu:.3f}", f"{fig.nfev:d}", f"{fig.error:.2e}",
            f"{fig.constraint:.1e}"]


def print_header(args, lib_time, base_time, reference):
    import numpy
    import scipy
    import sympy

    print("closedloop performance: slider-crank, case 2 (phi0 = pi/2, phi0' = 1 rad/s), 0 .. 20 s")
    print(f"python {sys.version.split()[0]}, numpy {numpy.__version__}, scipy {scipy.__version__}, "
          f"sympy {sympy.__version__}; mode: {'quick' if args.quick else 'full'}, "
          f"repeats = {args.repeats}, tolerances = {', '.join(f'{t:.0e}' for t in args.tolerances)}")
    print()
    lib = "n/a (already cached)" if lib_time is None else f"{lib_time:.3f} s"
    print(f"Derivation (CPU):  library slider_crank_system() first call {lib};  "
          f"baseline LagrangesMethod + lambdify {base_time:.3f} s")
    print(f"Reference: Minimal, DOP853, rtol = atol = {REFERENCE_TOL:.0e}; state at t = {T_CHECK:g} s:")
    print("  s  = [" + ", ".join(f"{v:.12f}" for v in reference[:3]) + "]")
    print("  s' = [" + ", ".join(f"{v:.12f}" for v in reference[3:]) + "]")
    print()


def print_fixed_tolerance(rows):
    print(f"Table 1. All methods at rtol = atol = {TABLE1_TOL:.0e} "
          "(CPU = median process time of a 20 s run)")
    headers = ["formulation", "method", "rtol", "CPU [s]", "nfev", "err@10s", "max|f|"]
    print(table(headers, [[label] + figure_cells(fig) for label, fig in rows]))
    print()


def print_equal_accuracy(results, baseline_label, capped):
    print(f"Table 2. Equal accuracy: loosest rtol (= atol) with err@10s <= {ERROR_TARGET:.0e}, per method")
    headers = ["formulation", "method", "rtol", "CPU [s]", "nfev", "err@10s", "max|f|", "best"]
    rows = []
    for label, per_method in results.items():
        best = best_of(per_method)
        for method, fig in per_method.items():
            mark = "*" if fig is not None and fig is best else ""
            cells = figure_cells(fig) if fig is not None else [method, "-", "-", "-", "-", "-"]
            rows.append([label] + cells + [mark])
    print(table(headers, rows))
    if capped:
        print(f"  (baseline accuracy runs were capped at {BASELINE_BUDGET:g} s CPU each; "
              "a capped tolerance counts as not meeting the target)")
    print()
    base = best_of(results[baseline_label])
    print("Speed-up at equal accuracy = baseline CPU / library CPU (each with its best method; > 1: library faster)")
    rows, ratios = [], {}
    for label, per_method in results.items():
        if label == baseline_label:
            continue
        fig = best_of(per_method)
        if fig is None or base is None:
            rows.append([label, "-", "-", "-", "-"])
            continue
        ratios[label] = base.cpu / fig.cpu
        rows.append([label, fig.method, f"{fig.rtol:.0e}", f"{fig.cpu:.3f}", f"{ratios[label]:.2f}"])
    base_cells = ["-"] * 3 if base is None else [base.method, f"{base.rtol:.0e}", f"{base.cpu:.3f}"]
    rows.append([baseline_label] + base_cells + ["1.00" if base is not None else "-"])
    print(table(["formulation", "method", "rtol", "CPU [s]", "speed-up"], rows))
    if ratios:
        label = max(ratios, key=ratios.get)
        print(f"Best speed-up: {ratios[label]:.2f}x ({label})")
    print()


def best_of(per_method):
    """The method's Figures with the lowest CPU time, or None if none met the target."""
    met = [fig for fig in per_method.values() if fig is not None]
    return min(met, key=lambda fig: fig.cpu) if met else None


# -- main --------------------------------------------------------------------------------------
def parse_args(argv):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true",
                        help=f"1 repeat and tolerances {', '.join(f'{t:.0e}' for t in QUICK_TOLERANCES)} "
                             "(well under a minute)")
    args = parser.parse_args(argv)
    args.repeats = 1 if args.quick else 3
    args.tolerances = QUICK_TOLERANCES if args.quick else FULL_TOLERANCES
    return args


def main(argv=None):
    args = parse_args(argv)
    wall = time.perf_counter()
    system, lib_time = library_system()          # first: the derivation is cached afterwards

    from closedloop import Minimal
    from closedloop.slider_crank import CASES, initial_state

    case = CASES[2]
    ic = initial_state(system, case.phi0, case.dphi0)
    mass_full, forcing_full, base_time = derive_baseline(system.parameters)
    reference = library_runner(system, ic, Minimal())("DOP853", REFERENCE_TOL, T_CHECK)[2]
    print_header(args, lib_time, base_time, reference)

    baseline_label = "baseline (sympy)"
    runners = {label: library_runner(system, ic, f) for label, f in library_formulations()}
    runners[baseline_label] = baseline_runner(system.parameters, ic, mass_full, forcing_full)

    fixed = [(label, measure(run, method, TABLE1_TOL, reference, args.repeats))
             for label, run in runners.items() for method in METHODS]
    print_fixed_tolerance(fixed)

    results, capped = {}, False
    for label, run in runners.items():
        results[label] = {}
        for method in METHODS:
            fig, was_capped = equal_accuracy(run, method, args.tolerances, reference, args.repeats)
            results[label][method] = fig
            capped = capped or (was_capped and label == baseline_label)
    print_equal_accuracy(results, baseline_label, capped)
    print(f"Total wall time of this benchmark: {time.perf_counter() - wall:.0f} s")


if __name__ == "__main__":
    main()
