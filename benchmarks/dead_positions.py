"""The sweep of issue 34 over a rocking crank's dead positions: every formulation x method x tolerance, counted.

The rocking slider-crank (l1 = 2 m, l2 = 1.5 m, no torque, no gas force, phi0 = 0, phi0' = 1 rad/s, 5 s)
passes dead positions of phi at about 2.21 s and 4.79 s. Each run is right (phi(5) within 100 times
atol + rtol |phi(5)| of the equation in the rod angle, tests/test_dead_positions.py), refused (a
ClosedLoopError that names the time) or wrong (anything else: another phi(5), another exception, no
answer within a minute). tests/test_dead_positions.py runs the same sweep at 1e-6 and 1e-9 and
requires wrong = 0; this script prints every run, and takes other tolerances.

    python benchmarks/dead_positions.py [--tolerances 1e-6 1e-9]

It uses only the public API and the test's reference, so it runs on an older checkout too (put that
checkout's src first on PYTHONPATH) and gives the counts before a change.
"""

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from closedloop.simulation.options import methods_taking  # noqa: E402
from closedloop.slider_crank import initial_state, slider_crank_system  # noqa: E402
from tests.test_dead_positions import (FORMULATIONS, ROCKING, START, TOLERANCES, outcome,  # noqa: E402
                                       psi_coordinate_equation, rocking_solution)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tolerances", type=float, nargs="+", default=list(TOLERANCES))
    args = parser.parse_args()
    solution = rocking_solution()
    phi_exact = psi_coordinate_equation(ROCKING)[2](solution.y[0, -1])
    system = slider_crank_system(ROCKING, torque=False, gas=False)
    state = initial_state(system, *START)
    counts = {"right": 0, "refused": 0, "wrong": 0}
    print(f"phi(5) of the equation in the rod angle: {phi_exact:.10f} rad")
    for formulation in FORMULATIONS:
        for method in methods_taking(formulation):
            for tolerance in args.tolerances:
                start = time.perf_counter()
                kind, detail = outcome(system, state, formulation, method, tolerance, phi_exact)
                counts[kind] += 1
                text = "" if detail is None else str(detail)[:150]
                print(f"{formulation!r:45} {method:10} {tolerance:6.0e} {kind:8} {time.perf_counter() - start:6.2f} s "
                      f"{text}", flush=True)
    print(f"right {counts['right']}, refused {counts['refused']}, wrong {counts['wrong']}")


if __name__ == "__main__":
    main()
