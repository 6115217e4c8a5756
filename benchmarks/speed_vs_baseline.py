"""The library's best route against the sympy.physics.mechanics baseline at e10 <= 1e-8, in one run.

For each of the paper's four cases this finds, for the baseline
(:class:`closedloop.studies.baseline.LagrangesBaseline`: LagrangesMethod, lambdify, solve_ivp
through the gas force's switches) and for the library, the cheapest (method, rtol) whose error at
t = 10 s, ``e10 = max_k |y_k(10) - y_k,ref(10)|``, is at most 1e-8, and prints both CPU times and
their ratio.  Every run integrates 0-20 s (the study's run) and outputs the state at 10 s only.

- The reference is the study's: minimal coordinates, DOP853, rtol = atol = 1e-13.
- Screening (one run per row, untimed, which also warms every generated function): each
  candidate's tolerances run from loose to tight, on a grid of 1, 2 and 5 per decade
  (atol = rtol), and the loosest that reaches the target qualifies, as in the study
  (``best_row``: the cheapest row with e10 <= 1e-8; the cost grows as rtol falls).  With
  ``--reliable`` a tolerance qualifies only when every tighter one screened reaches the target
  too (errors near the target wander from one tolerance to the next).  A candidate's screening
  stops at the first tolerance whose run takes longer than ``--cap`` seconds.
- Timing: the qualifying row of each method (its loosest) runs ``--repeats`` times, the rows of
  both sides interleaved, and each keeps its smallest process time (``time.process_time``).
  The best of each side is the smallest of those.

    python benchmarks/speed_vs_baseline.py [--repeats 7] [--cases 1 2 3 4] [--modules numpy math]

The baseline runs lambdified for sympy's default numpy printer and for Python's math module (see
the baseline's module notes), each a candidate of its own: its best is the cheapest of both
printers.  ``--modules numpy`` (or ``math``) times one printer only.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from closedloop import simulate
from closedloop.formulations import Augmented, ClosedForm, Minimal
from closedloop.slider_crank import get_case, initial_state, slider_crank_system
from closedloop.studies.baseline import LagrangesBaseline

T_END, T_CHECK, TARGET = 20.0, 10.0, 1e-8
RTOLS = tuple(sorted((m * 10.0 ** -k for k in range(8, 13) for m in (5.0, 2.0, 1.0)), reverse=True))
BASELINE_METHODS = ("LSODA", "DOP853", "RK45", "BDF", "Radau")
LIBRARY_ROUTES = (("closed form (1, 1)", lambda: ClosedForm(1, 1), "ode.dop853"),
                  ("closed form (1, 1)", lambda: ClosedForm(1, 1), "DOP853"),
                  ("augmented", Augmented, "DOP853"))


def baseline_run(baseline, state, method, rtol):
    def run():
        res = baseline.simulate(state, T_END, method, rtol, rtol, t_eval=(T_CHECK,))
        return np.concatenate((res.s[:, 0], res.sd[:, 0]))
    return run


def library_run(system, state, make, method, rtol):
    formulation = make()

    def run():
        res = simulate(system, state, T_END, formulation=formulation, method=method, rtol=rtol, atol=rtol,
                       t_eval=(T_CHECK,))
        return np.concatenate((res.s[:, 0], res.sd[:, 0]))
    return run


def screen(make_run, reference, cap, reliable=False):
    """``(rtol, e10)`` of the loosest qualifying tolerance of one candidate, or None."""
    errors = []
    for rtol in RTOLS:
        start = time.process_time()
        try:
            y = make_run(rtol)()
        except Exception as error:                       # a failed run does not qualify
            errors.append((rtol, math.inf, str(error)[:60]))
            continue
        errors.append((rtol, float(np.abs(y - reference).max()), ""))
        if time.process_time() - start > cap or (not reliable and errors[-1][1] <= TARGET):
            break
    if not reliable:
        return next(((rtol, error) for rtol, error, _ in errors if error <= TARGET), None)
    qualifying = None
    for rtol, error, _ in reversed(errors):              # tight to loose: stop at the first miss
        if error > TARGET:
            break
        qualifying = (rtol, error)
    return qualifying


def best_cpu(runs, repeats):
    """Smallest process time of each run, the runs interleaved."""
    best = [math.inf] * len(runs)
    for _ in range(repeats):
        for k, run in enumerate(runs):
            start = time.process_time()
            run()
            best[k] = min(best[k], time.process_time() - start)
    return best


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--cases", type=int, nargs="+", default=[1, 2, 3, 4])
    parser.add_argument("--modules", choices=("numpy", "math"), nargs="+", default=["numpy", "math"])
    parser.add_argument("--cap", type=float, default=0.6, help="screening stops after a run this long [s]")
    parser.add_argument("--reliable", action="store_true", help="every tighter rtol must reach the target too")
    args = parser.parse_args()
    system = slider_crank_system()
    baselines = {printer: LagrangesBaseline(system.parameters, system.reading, modules=printer)
                 for printer in args.modules}
    print(f"e10 <= {TARGET:g}; baseline lambdified for {', '.join(args.modules)}; CPU = best of {args.repeats} "
          f"interleaved runs (process time){'; reliable tolerances' if args.reliable else ''}\n")
    header = (f"{'case':>4}  {'baseline best':<32} {'e10':>8} {'CPU [ms]':>9}  {'library best':<34} {'e10':>8} "
              f"{'CPU [ms]':>9}  {'ratio':>6}")
    lines, ratios = [header, "-" * len(header)], []
    for case in args.cases:
        chosen = get_case(case)
        state = initial_state(system, chosen.phi0, chosen.dphi0)
        ref = simulate(system, state, T_END, formulation=Minimal(), method="DOP853", rtol=1e-13, atol=1e-13,
                       t_eval=(T_CHECK,))
        reference = np.concatenate((ref.s[:, 0], ref.sd[:, 0]))
        candidates = []                                  # (side, label, rtol, e10, run)
        for (printer, baseline), method in ((b, m) for b in baselines.items() for m in BASELINE_METHODS):
            found = screen(lambda rtol, b=baseline, m=method: baseline_run(b, state, m, rtol), reference, args.cap,
                           args.reliable)
            if found:
                candidates.append(("baseline", f"{method} ({printer})", *found,
                                   baseline_run(baseline, state, method, found[0])))
        for label, make, method in LIBRARY_ROUTES:
            found = screen(lambda rtol, mk=make, m=method: library_run(system, state, mk, m, rtol), reference,
                           args.cap, args.reliable)
            if found:
                candidates.append(("library", f"{label}, {method}", *found,
                                   library_run(system, state, make, method, found[0])))
        cpu = best_cpu([c[4] for c in candidates], args.repeats)
        best = {}
        for candidate, seconds in zip(candidates, cpu):
            side = candidate[0]
            print(f"  case {case} {side:8s} {candidate[1]:<32} rtol {candidate[2]:.0e}  e10 {candidate[3]:.1e}  "
                  f"{1e3 * seconds:8.2f} ms")
            if side not in best or seconds < best[side][1]:
                best[side] = (candidate, seconds)
        if len(best) < 2:
            lines.append(f"{case:>4}  a side reached no tolerance with e10 <= {TARGET:g}: {sorted(best)}")
            continue
        (base, base_cpu), (lib, lib_cpu) = best["baseline"], best["library"]
        ratios.append((base_cpu / lib_cpu, case, f"{base[1]}, rtol {base[2]:.0e}", f"{lib[1]}, rtol {lib[2]:.0e}"))
        lines.append(f"{case:>4}  {base[1] + ', rtol ' + format(base[2], '.0e'):<32} {base[3]:8.1e} "
                     f"{1e3 * base_cpu:9.2f}  {lib[1] + ', rtol ' + format(lib[2], '.0e'):<34} {lib[3]:8.1e} "
                     f"{1e3 * lib_cpu:9.2f}  {base_cpu / lib_cpu:6.2f}")
    print()
    print("\n".join(lines))
    if ratios:
        print(f"\nbaseline CPU / library CPU, each side at its cheapest configuration with e10 <= {TARGET:g}:")
        for label, (ratio, case, base, lib) in (("lowest", min(ratios)), ("highest", max(ratios))):
            print(f"  {label:7s} {ratio:6.2f}  case {case}: the baseline's {base} against the library's {lib}")


if __name__ == "__main__":
    main()
