"""What reaching the compiled DOP853 through scipy's public ``scipy.integrate.ode`` costs, old against new, in one run.

    python benchmarks/dop853_public_cost.py [--repeats 7] [--t-end 20]

Two routes to the same compiled code (Hairer and Wanner's DOP853 in scipy):

- *private* (before issue 35): the extension module ``scipy.integrate._dop`` called with the argument
  list that scipy's private ``_ode.py`` passes (its code is copied here, as it was in
  ``closedloop/simulation/dop853_code.py``);
- *public* (now): :func:`closedloop.simulation.dop853_code.dopri853`, an ``ode(f).set_integrator("dop853")``
  per call.

Each of the paper's four cases is simulated over ``--t-end`` seconds with ``ClosedForm(1, 1)``,
``method="ode.dop853"``, rtol = atol = 1e-9, once with each route (``dop853_code.dopri853`` replaced
for the private one), the routes taking turns, ``--repeats`` times; the smallest process time of each
is kept.  It checks that both routes give the same nfev, steps and end state to the bit, and prints the
process times and their ratio (public / private), per case and summed: the issue's limit is 1.20.
A second table does the same for a run with 2001 output times (t_eval), and a third for the calls
alone (a short integration of a pendulum, as the switch location makes them).  The start-up cost of
the command is ``benchmarks/cli_time.py --before REV``'s.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

import closedloop
from closedloop.simulation import dop853_code
from closedloop.slider_crank import CASES, initial_state, slider_crank_system


def private_dopri853(f, t0, y0, t_end, *, rtol, atol, nsteps, first_step=0.0, max_step=0.0, solout=None,
                     dfactor=dop853_code.DFACTOR, beta=dop853_code.BETA):
    """The route before issue 35: scipy's private extension, called as scipy's private ``_ode.py`` calls it."""
    from scipy.integrate import _dop        # private: the very thing the library no longer does

    y = np.asarray(y0, dtype=float).copy()
    n = len(y)
    work = np.zeros((11 * n + 21,), float)
    work[1], work[2], work[3], work[4] = dop853_code.SAFETY, dfactor, dop853_code.IFACTOR, beta
    work[5], work[6] = max_step, first_step
    iwork = np.zeros((21,), dtype=np.int32)
    t, y, code = _dop.dopri853(f, t0, y, t_end, rtol, atol, solout or (lambda t, y: 0), 1, work, iwork, nsteps,
                               dop853_code.VERBOSITY, ())
    return t, y, code


PUBLIC = dop853_code.dopri853


def run(route, system, state, t_end, t_eval):
    dop853_code.dopri853 = route
    try:
        start = time.process_time()
        result = closedloop.simulate(system, state, t_end, formulation=closedloop.ClosedForm(1, 1),
                                     method="ode.dop853", rtol=1e-9, atol=1e-9, t_eval=t_eval)
        return time.process_time() - start, result
    finally:
        dop853_code.dopri853 = PUBLIC


def table(title, system, repeats, t_end, t_eval):
    print(title)
    print(f"{'case':>4}  {'nfev':>6}  {'steps':>6}  {'private s':>10}  {'public s':>10}  {'public / private':>16}")
    totals = [0.0, 0.0]
    for case in CASES:
        state = initial_state(system, CASES[case].phi0, CASES[case].dphi0)
        best = [math.inf, math.inf]
        results = [None, None]
        run(PUBLIC, system, state, t_end, t_eval)                   # warm: generated code, first imports
        run(private_dopri853, system, state, t_end, t_eval)
        for _ in range(repeats):
            for k, route in enumerate((private_dopri853, PUBLIC)):
                cpu, results[k] = run(route, system, state, t_end, t_eval)
                best[k] = min(best[k], cpu)
        old, new = results
        same = (old.nfev == new.nfev and old.n_steps == new.n_steps and np.array_equal(old.s, new.s)
                and np.array_equal(old.sd, new.sd))
        if not same:
            raise SystemExit(f"case {case}: the two routes differ (nfev {old.nfev} / {new.nfev})")
        totals[0] += best[0]
        totals[1] += best[1]
        print(f"{case:>4}  {new.nfev:>6}  {new.n_steps:>6}  {best[0]:>10.4f}  {best[1]:>10.4f}  "
              f"{best[1] / best[0]:>16.3f}")
    print(f"{'all':>4}  {'':>6}  {'':>6}  {totals[0]:>10.4f}  {totals[1]:>10.4f}  {totals[1] / totals[0]:>16.3f}")
    print()
    return totals[1] / totals[0]


def calls_alone(repeats, count=2000):
    """``count`` short integrations (a pendulum over 0.01 s): the cost per call of each route."""
    def pendulum(t, y):
        return [y[1], -math.sin(y[0])]

    y0 = np.array([1.0, 0.0])
    best = [math.inf, math.inf]
    for _ in range(repeats):
        for k, route in enumerate((private_dopri853, PUBLIC)):
            start = time.process_time()
            for _ in range(count):
                route(pendulum, 0.0, y0, 0.01, rtol=1e-9, atol=1e-9, nsteps=1000)
            best[k] = min(best[k], (time.process_time() - start) / count)
    print(f"one short call (pendulum, 0.01 s): private {best[0] * 1e6:.1f} us, public {best[1] * 1e6:.1f} us, "
          f"public / private {best[1] / best[0]:.3f}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--t-end", type=float, default=20.0)
    args = parser.parse_args()
    system = slider_crank_system()
    ratio = table(f"ode.dop853, ClosedForm(1, 1), rtol = atol = 1e-9, {args.t_end:g} s, no t_eval "
                  f"(best of {args.repeats}):", system, args.repeats, args.t_end, None)
    grid = np.linspace(0.0, args.t_end, 2001)
    ratio_grid = table(f"the same with 2001 output times:", system, args.repeats, args.t_end, grid)
    calls_alone(args.repeats)
    worst = max(ratio, ratio_grid)
    print(f"public / private, whole runs: {ratio:.3f} without outputs, {ratio_grid:.3f} with them; "
          f"{'within' if worst <= 1.2 else 'beyond'} the limit 1.20")


if __name__ == "__main__":
    main()
