"""What the watch along the steps costs, and what a run that fails costs: ratios from one run on one machine.

1. The watch (closedloop.simulation.watch: change points, the branch guard at det Phi_z = 0, dead
   positions of Minimal, crawling) checks the step ends of every run in batches as it goes. The paper's
   four cases with it on and with the check for change points off (``branch_limit=math.inf``, which
   keeps the rest), each pair interleaved and repeated, the smallest process time of each kept.
2. A run that fails costs about what the run up to the failure costs: a parallelogram four-bar started
   with the crank up, turning down, folds onto the x axis (a change point) at 0.722 s; the same run to
   10 s and to 0.75 s, per formulation and method, raise there, and their times are compared. Before
   the watch the 10 s runs integrated on to t_end first (NullSpace with Radau: 4.3 s against 0.034 s).

    python benchmarks/change_point_cost.py [--repeats 7] [--t-end 40] [--skip-cases]
"""

import argparse
import math
import time

import numpy as np

from closedloop import SingularConfigurationError, System, consistent_initial_state, simulate
from closedloop.formulations import formulation_from_name
from closedloop.four_bar import four_bar_model
from closedloop.slider_crank import get_case, initial_state, slider_crank_system

PARALLELOGRAM = {"l0": 3.0, "l1": 1.0, "l2": 3.0, "l3": 1.0, "m1": 1.0, "m2": 2.0, "m3": 1.0, "g": 9.81}
FAILING = (("baumgarte", "RK45"), ("baumgarte", "DOP853"), ("nullspace", "Radau"), ("augmented", "LSODA"),
           ("closed-form", "ode.dop853"), ("minimal", "DOP853"), ("projected", "DOP853"))


def cpu(function, repeats):
    best = math.inf
    for _ in range(repeats):
        start = time.process_time()
        function()
        best = min(best, time.process_time() - start)
    return best


def watch_cost(repeats, t_end):
    system = slider_crank_system()
    print(f"{'case':>4} {'formulation':>12} {'method':>10} {'watch on [s]':>13} {'off [s]':>9} {'ratio':>6}")
    ratios = []
    for case in (1, 2, 3, 4):
        chosen = get_case(case)
        state = initial_state(system, chosen.phi0, chosen.dphi0)
        for name, method in (("baumgarte", "RK45"), ("orthogonal", "DOP853"), ("minimal", "DOP853"),
                             ("closed-form", "ode.dop853")):
            formulation = formulation_from_name(name)

            def run(limit):
                return lambda: simulate(system, state, t_end, formulation=formulation, method=method,
                                        rtol=1e-9, atol=1e-9, branch_limit=limit)

            on = off = math.inf
            for _ in range(repeats):                    # interleaved: the same machine state for both
                on = min(on, cpu(run(0.01), 1))
                off = min(off, cpu(run(math.inf), 1))
            ratios.append(on / off)
            print(f"{case:>4} {name:>12} {method:>10} {on:13.4f} {off:9.4f} {on / off:6.3f}")
    print(f"largest ratio {max(ratios):.3f}, geometric mean {math.prod(ratios) ** (1 / len(ratios)):.3f}")


def failure_cost(repeats):
    system = System(four_bar_model(), PARALLELOGRAM)
    start = consistent_initial_state(system, [np.pi / 2], [-1.0], [0.0, np.pi / 2])
    print(f"\n{'formulation':>12} {'method':>10} {'to 10 s [s]':>12} {'to 0.75 s [s]':>14} {'ratio':>6}  stops at")
    ratios = []
    for name, method in FAILING:
        formulation = formulation_from_name(name)
        stops = []

        def run(t_end):
            def attempt():
                try:
                    simulate(system, start, t_end, formulation=formulation, method=method)
                except SingularConfigurationError as error:
                    stops.append(float(str(error).split("at t = ")[1].split(" s")[0]))
                else:
                    raise AssertionError(f"{name} {method} to {t_end} s passed the change point")
            return attempt

        long = short = math.inf
        for _ in range(repeats):
            long = min(long, cpu(run(10.0), 1))
            short = min(short, cpu(run(0.75), 1))
        ratios.append(long / short)
        print(f"{name:>12} {method:>10} {long:12.4f} {short:14.4f} {long / short:6.2f}  {min(stops):.6g} to "
              f"{max(stops):.6g} s")
    print(f"largest ratio {max(ratios):.2f}, geometric mean {math.prod(ratios) ** (1 / len(ratios)):.2f}")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--t-end", type=float, default=40.0)
    parser.add_argument("--skip-cases", action="store_true", help="only the runs that fail")
    args = parser.parse_args()
    if not args.skip_cases:
        watch_cost(args.repeats, args.t_end)
    failure_cost(args.repeats)


if __name__ == "__main__":
    main()
