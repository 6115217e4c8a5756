"""What an output grid (t_eval) costs and changes: no grid, 10 000 and 50 000 output times, in one run.

For each method, case 2 of the paper (ClosedForm, rtol = atol = 1e-9 by default) is integrated
over ``--t-end`` seconds without t_eval and with evenly spaced output grids.  The runs of one
method are interleaved and repeated, and the smallest process time of each is kept, so the CPU
ratios are measured in one run on one machine.  Each timed run follows an untimed run of the same
grid: a run after a larger grid's finds the caches full of that run's arrays.  Measured that way (as
this script did before), the run without a grid took about 15 % longer, and the ratios came out too
low: 1.66 for 10 000 outputs with ode.dop853 over 1 s, where each grid timed after its own run
gives 1.84 to 1.86.  Printed per method and grid:

- nfev and its ratio to the run without a grid (a count: the same on every machine);
- CPU time and its ratio (process time, best of ``--repeats``);
- whether the accepted steps are those of the run without a grid, and the largest change of
  the end state against that run;
- the largest error of the outputs against a tight reference (Minimal, DOP853, rtol = atol =
  1e-13, at the same times), in units of the run's tolerance ``atol + rtol |y|`` (over s and s');
  the line without a grid gives the same at its own step ends.

For ode.dop853, what the outputs' extra CPU time is made of follows the table: the extra
right-hand sides (their count times the CPU of one call of the generated right-hand side alone,
timed on the run's own states), the arithmetic of the interpolant at the output times
alone (:func:`closedloop.simulation.dop853_dense.interpolate` over all of them, in the library's groups of
outputs, timed by itself: a floor no bookkeeping can go under), and the rest, the Python bookkeeping per step and
per segment (recording and checking the stages, holding the steps, gathering their outputs).

    python benchmarks/output_grid_cost.py [--repeats 5] [--t-end 1] [--methods ode.dop853 DOP853]
"""

import argparse
import math
import time

import numpy as np

from closedloop import Minimal, simulate
from closedloop.formulations import ClosedForm
from closedloop.simulation import dop853, dop853_dense
from closedloop.slider_crank import get_case, initial_state, slider_crank_system

GRIDS = (None, 10_000, 50_000)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--t-end", type=float, default=1.0)
    parser.add_argument("--case", type=int, default=2)
    parser.add_argument("--tol", type=float, default=1e-9, help="rtol = atol")
    parser.add_argument("--methods", nargs="+", default=["ode.dop853", "DOP853"])
    args = parser.parse_args()
    system = slider_crank_system()
    case = get_case(args.case)
    state = initial_state(system, case.phi0, case.dphi0)
    grids = {n: None if n is None else np.linspace(0.0, args.t_end, n) for n in GRIDS}

    def run(method, n):
        return simulate(system, state, args.t_end, formulation=ClosedForm(), method=method, rtol=args.tol,
                        atol=args.tol, t_eval=grids[n])

    print(f"case {args.case} over {args.t_end:g} s, ClosedForm, rtol = atol = {args.tol:g}; best of {args.repeats}")
    print(f"{'method':>10} {'outputs':>8} {'nfev':>7} {'ratio':>6} {'CPU [s]':>9} {'ratio':>6} {'steps':>6} "
          f"{'same steps':>10} {'end change':>10} {'error/tol':>9}")
    for method in args.methods:
        results, cpu = {}, {n: math.inf for n in GRIDS}
        for _ in range(args.repeats):                      # interleaved: the same machine state for all grids
            for n in GRIDS:
                run(method, n)                             # the caches as a run of this grid leaves them
                start = time.process_time()
                results[n] = run(method, n)
                cpu[n] = min(cpu[n], time.process_time() - start)
        plain = results[None]
        times = np.unique(np.concatenate([plain.t] + [grids[n] for n in GRIDS if n is not None]))
        reference = simulate(system, state, args.t_end, formulation=Minimal(), method="DOP853", rtol=1e-13,
                             atol=1e-13, t_eval=times)
        for n in GRIDS:
            result = results[n]
            at = np.searchsorted(reference.t, result.t)
            exact = np.vstack((reference.s[:, at], reference.sd[:, at]))
            error = np.max(np.abs(np.vstack((result.s, result.sd)) - exact) / (args.tol + args.tol * np.abs(exact)))
            same = (result.step_sizes.size == plain.step_sizes.size
                    and bool(np.all(result.step_sizes == plain.step_sizes)))
            end = max(np.max(np.abs(result.s[:, -1] - plain.s[:, -1])),
                      np.max(np.abs(result.sd[:, -1] - plain.sd[:, -1])))
            print(f"{method:>10} {'none' if n is None else n:>8} {result.nfev:7d} {result.nfev / plain.nfev:6.2f} "
                  f"{cpu[n]:9.4f} {cpu[n] / cpu[None]:6.2f} {result.n_steps:6d} {str(same):>10} {end:10.2g} "
                  f"{error:9.3g}")
        if method == dop853.METHOD:
            _extra_cost(results, cpu, _rhs_cost(system, results[10_000], args.repeats), args.repeats)


def _rhs_cost(system, result, repeats):
    """CPU [s] of one call of ClosedForm's generated right-hand side, at about 500 states of ``result``."""
    s0, sd0 = result.s[:, 0], result.sd[:, 0]
    rhs = ClosedForm().make_rhs(system, system.force.mode_at(result.t[0], s0, sd0), None)
    states = list(np.vstack((result.s, result.sd)).T[::max(1, result.t.size // 500)].copy())

    def calls():
        for y in states:
            rhs(0.5, y)

    return _best_process_time(calls, repeats) / len(states)


def _best_process_time(call, repeats):
    """The smallest process time [s] of ``call()`` over ``repeats`` calls (at least 5)."""
    best = math.inf
    for _ in range(max(repeats, 5)):
        start = time.process_time()
        call()
        best = min(best, time.process_time() - start)
    return best


def _extra_cost(results, cpu, per_evaluation, repeats):
    """Print what the outputs' extra CPU time of ode.dop853 is made of (see the module's docstring)."""
    size = results[None].s.shape[0] + results[None].sd.shape[0]
    rng = np.random.default_rng(0)
    F, ya = rng.standard_normal((7, size)), rng.standard_normal(size)
    print(f"{'':>10} extra CPU [ms] = extra right-hand sides ({1e6 * per_evaluation:.2f} us each) + "
          "interpolant's arithmetic alone + bookkeeping")
    for n in GRIDS:
        if n is None:
            continue
        # in pieces of the library's own group size: one call over 50 000 outputs would allocate, and fault
        # in, a 3 MB basis on every repeat, which is no floor (measured: from 0.3 to 4 ms)
        pieces = np.array_split(np.linspace(0.0, 1.0, n), math.ceil(n / dop853_dense._GROUP_OUTPUTS))
        arithmetic = _best_process_time(lambda: [dop853_dense.interpolate(F, ya, x) for x in pieces], repeats)
        extra = cpu[n] - cpu[None]
        calls = (results[n].nfev - results[None].nfev) * per_evaluation
        print(f"{'':>10} {n:>8} {1e3 * extra:7.3f} = {1e3 * calls:.3f} + {1e3 * arithmetic:.3f} "
              f"+ {1e3 * (extra - calls - arithmetic):.3f}")


if __name__ == "__main__":
    main()
