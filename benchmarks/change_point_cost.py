"""What the change-point watch costs: the paper's four cases with it on and off, in one run.

The watch (closedloop.simulation.change_points) checks sigma_min(Phi_s) at every step end of every
segment.  ``branch_limit=math.inf`` turns it off (with the branch guard at sign changes of det
Phi_z, which costs nothing where det Phi_z keeps its sign, as in these cases).  Each pair of runs is
interleaved and repeated, and the smallest process time of each is kept, so that the ratio is
measured in one run on one machine.

    python benchmarks/change_point_cost.py [--repeats 7] [--t-end 40]
"""

import argparse
import math
import time

from closedloop import simulate
from closedloop.formulations import formulation_from_name
from closedloop.slider_crank import get_case, initial_state, slider_crank_system


def cpu(function, repeats):
    best = math.inf
    for _ in range(repeats):
        start = time.process_time()
        function()
        best = min(best, time.process_time() - start)
    return best


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--t-end", type=float, default=40.0)
    args = parser.parse_args()
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
                return lambda: simulate(system, state, args.t_end, formulation=formulation, method=method,
                                        rtol=1e-9, atol=1e-9, branch_limit=limit)

            on = off = math.inf
            for _ in range(args.repeats):                    # interleaved: the same machine state for both
                on = min(on, cpu(run(0.01), 1))
                off = min(off, cpu(run(math.inf), 1))
            ratios.append(on / off)
            print(f"{case:>4} {name:>12} {method:>10} {on:13.4f} {off:9.4f} {on / off:6.3f}")
    print(f"largest ratio {max(ratios):.3f}, geometric mean {math.prod(ratios) ** (1 / len(ratios)):.3f}")


if __name__ == "__main__":
    main()
