"""Speed and agreement of the basin map (closedloop basin), measured in one run.

Run as ``python benchmarks/basin.py [--size 100] [--sample 300] [--workers W] [--serial]``.
Every figure printed comes from this run; nothing is read from earlier runs.
This is a benchmark script, not a test: it asserts nothing.

What is measured
----------------
wall, CPU
    ``BasinMap.wall_time`` and ``cpu_time`` of one ``basin_map`` call on a
    size x size grid, phi0 in [0, 2 pi), phi0' in [0, 3) rad/s, t = 0 .. 20 s,
    with ``--workers`` processes (default: one per core).  ``--serial`` also
    times the same map in one process.
agreement
    The reference classifies ``--sample`` cells drawn at random (seed
    ``--seed``), one :func:`closedloop.simulate` run per cell (ClosedForm, ode.dop853,
    rtol = atol = 1e-10; :func:`closedloop.studies.basin.reference_outcome`).  For every
    cell where map and reference disagree, the reference also classifies its
    four neighbours: the cell is "on the boundary" if one of them has the other
    outcome in the reference.
"""

from __future__ import annotations

import argparse
import math
import multiprocessing
import os
import time

import numpy as np

from closedloop.studies.basin import basin_map, grid_values, reference_outcome
from closedloop.slider_crank import slider_crank_system


def _reference(cell):
    phi0, dphi0 = cell
    return reference_outcome(slider_crank_system(), phi0, dphi0)


def references(cells, phi, dphi, workers):
    """Reference outcomes of (row, column) cells, in parallel."""
    points = [(phi[j], dphi[i]) for i, j in cells]
    slider_crank_system()                      # derive before forking
    with multiprocessing.get_context("fork").Pool(workers) as pool:
        return dict(zip(cells, pool.map(_reference, points, chunksize=4)))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=100)
    parser.add_argument("--sample", type=int, default=300, help="cells checked against the reference (0: none)")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--t-end", type=float, default=20.0)
    parser.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--serial", action="store_true", help="also time the map in one process")
    args = parser.parse_args()

    phi, dphi = grid_values(0.0, 2 * math.pi, args.size), grid_values(0.0, 3.0, args.size)
    print(f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f} at the start "
          "(shared machine: times are pessimistic)")
    basin = basin_map(phi, dphi, args.t_end, workers=args.workers)
    print(f"{args.size} x {args.size} map over {args.t_end:g} s, step {basin.step:g} s: "
          f"{basin.wall_time:.1f} s wall, {basin.cpu_time:.1f} s CPU, {args.workers} worker(s); "
          f"{basin.evaluations} vectorised evaluations ({basin.cell_evaluations} cell evaluations); "
          f"{100 * basin.fraction_rotating:.1f} % full rotation; max |f| = {basin.max_constraint_error:.1e}")
    if args.serial:
        serial = basin_map(phi, dphi, args.t_end, workers=1)
        same = int(np.sum(serial.outcome == basin.outcome))
        print(f"  in one process: {serial.wall_time:.1f} s wall ({same} of {serial.outcome.size} cells identical)")

    if args.sample <= 0:                       # the timing alone (benchmarks/timings.py)
        return
    rng = np.random.default_rng(args.seed)
    flat = rng.choice(basin.outcome.size, size=min(args.sample, basin.outcome.size), replace=False)
    cells = [tuple(int(v) for v in divmod(int(k), args.size)) for k in flat]
    start = time.perf_counter()
    reference = references(cells, phi, dphi, args.workers)
    seconds = time.perf_counter() - start
    wrong = [c for c in cells if reference[c] != basin.outcome[c]]
    print(f"reference (simulate, ClosedForm, ode.dop853, rtol 1e-10) on {len(cells)} random cells: "
          f"{seconds:.1f} s wall, {seconds / len(cells):.2f} s a cell")
    print(f"agreement: {len(cells) - len(wrong)} of {len(cells)} = {100 * (1 - len(wrong) / len(cells)):.2f} %")
    if wrong:
        near = sorted({(i + di, j + dj) for i, j in wrong for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1))
                       if 0 <= i + di < args.size and 0 <= j + dj < args.size} - set(reference))
        reference.update(references(near, phi, dphi, args.workers))
        for i, j in wrong:
            others = [reference[n] for n in ((i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1)) if n in reference]
            boundary = any(o != reference[(i, j)] for o in others)
            print(f"  disagree at row {i}, column {j}: phi0 = {phi[j]:.4f} rad, dphi0 = {dphi[i]:.4f} rad/s; "
                  f"map {basin.labels[basin.outcome[i, j]]}, reference {basin.labels[reference[(i, j)]]}; "
                  f"largest |phi - phi0| in the map {basin.excursion[i, j]:.4f} rad; "
                  f"{'on' if boundary else 'NOT on'} the reference's boundary")


if __name__ == "__main__":
    main()
